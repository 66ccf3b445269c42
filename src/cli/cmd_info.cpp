// arthrosim info FILE: a summary of a scenario (.yaml), a mesh (.msh .vtk .obj .stl) or a run
// (.h5): counts, bounds and units.
#include <fmt/core.h>

#include <filesystem>

#include "arthrosim/core/error.h"
#include "arthrosim/io/run_reader.h"
#include "arthrosim/io/scenario_loader.h"
#include "arthrosim/io/xdmf.h"
#include "arthrosim/mesh/mesh_io.h"
#include "arthrosim/mesh/mesh_summary.h"
#include "commands.h"

namespace arthrosim::cli {
namespace {

std::string Bounds(const Points& p) {
  if (p.cols() == 0) return "empty";
  const Vec3 lo = p.rowwise().minCoeff(), hi = p.rowwise().maxCoeff();
  return fmt::format("[{:.1f}, {:.1f}] x [{:.1f}, {:.1f}] x [{:.1f}, {:.1f}] mm", lo.x(), hi.x(),
                     lo.y(), hi.y(), lo.z(), hi.z());
}

void PrintScenario(const std::string& path) {
  const Model m = io::LoadScenario(path);
  fmt::print(
      "scenario {} ({})\n  sha256 {}\n  dt {} s, duration {} s, seed {}, gravity [{}, {}, {}] "
      "mm/s^2\n",
      m.name, path, m.scenario_sha256, m.options.dt_s, m.options.duration_s, m.options.seed,
      m.options.gravity_mm_s2.x(), m.options.gravity_mm_s2.y(), m.options.gravity_mm_s2.z());
  for (const SoftBodyModel& b : m.soft_bodies) {
    fmt::print("  soft   {:24} {:6} nodes {:6} tets  E {} Pa  nu {}  rho {} kg/m^3  fixed {}  {}\n",
               b.name, b.rest_mesh.nodes.cols(), b.rest_mesh.tets.size(),
               b.material.young_modulus_pa, b.material.poisson_ratio, b.material.density_kg_m3,
               b.fixed_nodes.size(), Bounds(b.rest_mesh.nodes));
  }
  for (const BoneModel& b : m.bones) {
    fmt::print("  rigid  {:24} {:6} nodes {:6} tris  {}\n", b.name, b.surface.nodes.cols(),
               b.surface.tris.size(), Bounds(b.surface.nodes));
  }
  for (const ThreadModel& t : m.threads) {
    fmt::print("  thread {:24} {:6} nodes  diameter {} mm  {}\n", t.name, t.initial.nodes.cols(),
               t.diameter_mm, Bounds(t.initial.nodes));
  }
  for (const InstrumentModel& i : m.instruments) {
    fmt::print("  instrument {:20} {:16} portal {}\n", i.name, InstrumentKindName(i.kind),
               i.portal);
  }
  fmt::print("  {} portals, {} landmarks, {} regions, {} joins\n", m.portals.size(),
             m.landmarks.size(), m.regions.size(), m.joins.size());
}

void PrintMesh(const std::string& path) {
  fmt::print("mesh {}\n{}", path, mesh::FormatSummary(mesh::Summarize(mesh::ReadMesh(path))));
}

}  // namespace

void AddInfoCommand(CLI::App* app, int* exit_code) {
  auto* cmd = app->add_subcommand("info", "Summarise a scenario, mesh or run file");
  auto path = std::make_shared<std::string>();
  cmd->add_option("file", *path, "Scenario (.yaml), mesh (.msh .vtk .obj .stl) or run (.h5)")
      ->required();
  auto write_xdmf = std::make_shared<bool>(false);
  cmd->add_flag("--write-xdmf", *write_xdmf,
                "Run file: (re)write its ParaView sidecar <run>.xmf from the file (e.g. after a "
                "killed run)");
  auto write_xdmf2 = std::make_shared<bool>(false);
  cmd->add_flag("--write-xdmf2", *write_xdmf2,
                "Run file: write <run>.xdmf2.xmf, the sidecar for ParaView's legacy XDMFReader");
  cmd->callback([path, write_xdmf, write_xdmf2, exit_code] {
    const std::string ext = std::filesystem::path(*path).extension().string();
    if (*write_xdmf && ext != ".h5" && ext != ".hdf5") {
      throw InputError(*path, 0, "--write-xdmf", "needs a run file (.h5)");
    }
    if (*write_xdmf2 && ext != ".h5" && ext != ".hdf5") {
      throw InputError(*path, 0, "--write-xdmf2", "needs a run file (.h5)");
    }
    if (ext == ".yaml" || ext == ".yml") {
      PrintScenario(*path);
    } else if (ext == ".h5" || ext == ".hdf5") {
      std::string text = io::Summarize(*path);
      if (!text.empty() && text.back() != '\n') text += '\n';
      fmt::print("{}", text);
      if (*write_xdmf) {
        const std::string xmf = io::XdmfPathFor(*path);
        io::WriteFileAtomically(xmf, io::XdmfText(io::XdmfRunFromFile(*path)));
        fmt::print("wrote {}\n", xmf);
      }
      if (*write_xdmf2) {
        const std::string xmf = io::XdmfPathFor(*path, io::XdmfDialect::kXdmf2);
        io::WriteFileAtomically(xmf,
                                io::XdmfText(io::XdmfRunFromFile(*path), io::XdmfDialect::kXdmf2));
        fmt::print("wrote {}\n", xmf);
      }
    } else {
      PrintMesh(*path);
    }
    *exit_code = kExitOk;
  });
}

}  // namespace arthrosim::cli
