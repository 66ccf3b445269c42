#pragma once
// A test scene for the grasping and suturing operations: a tendon slab (x in [0, 30], y in
// [0, 20], z in [0, 4] mm, 2 mm Kuhn-cube tets) fixed at x = 0 with its torn edge (`tendon_edge`)
// at x = 30, a suture thread above it, no gravity; written to a temporary folder and loaded as
// a scenario. Tool helpers drive one slot through sim::Step.
#include <unistd.h>

#include <gtest/gtest.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "arthrosim/core/parallel.h"
#include "arthrosim/io/scenario_loader.h"
#include "arthrosim/sim/step.h"

namespace arthrosim::testing {

inline constexpr int kSlabNx = 15, kSlabNy = 10, kSlabNz = 2;  // 2 mm cells
inline constexpr double kSlabCellMm = 2.0;

inline std::string WriteSlabVtk() {
  const auto id = [](int i, int j, int k) { return (k * (kSlabNy + 1) + j) * (kSlabNx + 1) + i; };
  std::vector<Vec3> p;
  for (int k = 0; k <= kSlabNz; ++k)
    for (int j = 0; j <= kSlabNy; ++j)
      for (int i = 0; i <= kSlabNx; ++i) p.push_back(kSlabCellMm * Vec3(i, j, k));
  std::vector<std::array<int, 4>> tets;
  const int perms[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  for (int k = 0; k < kSlabNz; ++k)
    for (int j = 0; j < kSlabNy; ++j)
      for (int i = 0; i < kSlabNx; ++i)
        for (const auto& perm : perms) {  // Kuhn path 000 -> e_a -> e_a + e_b -> 111
          std::array<int, 3> c{i, j, k};
          std::array<int, 4> t{};
          t[0] = id(c[0], c[1], c[2]);
          for (int s = 0; s < 3; ++s) {
            c[static_cast<std::size_t>(perm[s])] += 1;
            t[static_cast<std::size_t>(s) + 1] = id(c[0], c[1], c[2]);
          }
          const Vec3 a = p[t[0]], b = p[t[1]], cc = p[t[2]], d = p[t[3]];
          if ((b - a).cross(cc - a).dot(d - a) < 0) std::swap(t[2], t[3]);
          tets.push_back(t);
        }
  std::ostringstream s;
  s << "# vtk DataFile Version 3.0\nslab\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS " << p.size()
    << " double\n";
  for (const Vec3& q : p) s << q.x() << " " << q.y() << " " << q.z() << "\n";
  s << "CELLS " << tets.size() << " " << 5 * tets.size() << "\n";
  for (const auto& t : tets) s << "4 " << t[0] << " " << t[1] << " " << t[2] << " " << t[3] << "\n";
  s << "CELL_TYPES " << tets.size() << "\n";
  for (std::size_t k = 0; k < tets.size(); ++k) s << "10\n";
  return s.str();
}

/// A slab scenario named `name` in a temporary folder of its own: the slab tendon (Young's
/// modulus in Pa) fixed at x = 0 with its torn edge region, the thread bodies `threads` (YAML
/// list entries), the lateral portal at `portal` ("[x, y, z]"), then `rest` (instruments,
/// camera and any further sections) as written.
inline Model LoadSlabScenario(const std::string& name, double young_modulus_pa,
                              const std::string& threads, const std::string& portal,
                              const std::string& rest) {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() /
      ("arthrosim_" + name + "_" + std::to_string(getpid()));  // parallel test processes apart
  std::filesystem::create_directories(dir);
  { std::ofstream(dir / "slab.vtk") << WriteSlabVtk(); }
  const std::string yaml =
      "name: " + name + R"(
seed: 1
time: {dt: 0.02, duration: 1}
gravity: [0, 0, 0]
solver: {integrator: implicit_euler, cg_max_iterations: 200, cg_tolerance: 1.0e-8}
output: {file: slab.h5, every: 1}
materials:
  tendon: {young_modulus: )" +
      std::to_string(young_modulus_pa) +
      R"(, poisson_ratio: 0.4, density: 1100, rayleigh_mass: 1, rayleigh_stiffness: 0.01}
bodies:
  - {name: tendon, kind: soft, mesh: slab.vtk, material: tendon, fixed: [slab_base]}
)" + threads +
      R"(regions:
  - {name: slab_base, body: tendon, box: {min: [-1, -1, -1], max: [0.5, 21, 5]}}
  - {name: tendon_edge, body: tendon, box: {min: [29.5, -1, -1], max: [31, 21, 5]}}
portals:
  - {name: lateral, position: )" +
      portal + "}\n" + rest;
  const std::string path = (dir / "slab.yaml").string();
  { std::ofstream(path) << yaml; }
  return io::LoadScenario(path);
}

/// The slab scene; `extra` is appended to the YAML (e.g. an `operations:` section). The slab's
/// Young's modulus (Pa): stiff enough by default that a jerk outruns a grasp; 2 linear tets
/// through its thickness make it far stiffer in bending than the beam formula says.
inline Model SlabModel(const std::string& extra = "", double young_modulus_pa = 5e6) {
  return LoadSlabScenario("suture_slab", young_modulus_pa,
                          R"(  - name: suture
    kind: thread
    thread: {start: [6, 10, 8], end: [46, 10, 8], nodes: 41, damping: 5, fixed_nodes: [0]}
)",
                          "[60, 10, 30]", R"(instruments:
  - {name: grasper, kind: grasper, portal: lateral}
  - {name: retriever, kind: retriever, portal: lateral}
  - {name: scorpion_needle, kind: scorpion_needle, portal: lateral, tip_length: 8}
  - {name: hook, kind: hook, portal: lateral}
camera: {portal: lateral, position: [50, 10, 20], look_at: [10, 10, 5]}
)" + extra);
}

/// The orientation whose tool x, y and z axes point along the world directions given (an
/// orthonormal right-handed set).
inline Quat ToolAxes(const Vec3& x, const Vec3& y, const Vec3& z) {
  Mat3 r;
  r.col(0) = x;
  r.col(1) = y;
  r.col(2) = z;
  return Quat(r);
}

/// The States `run(model)` ends in with one worker thread and with two; the thread count is one
/// again afterwards.
template <class Run>
std::pair<State, State> RunWithOneAndTwoThreads(const Model& model, Run run) {
  SetThreadCount(1);
  State one = run(model);
  SetThreadCount(2);
  State two = run(model);
  SetThreadCount(1);
  return {std::move(one), std::move(two)};
}

/// Pointing straight down (tool +z = world -z), jaws opening along world x.
inline Quat Downward() { return Quat(Eigen::AngleAxisd(3.14159265358979323846, Vec3::UnitX())); }

/// Drives tool slot 0 with `instrument` (camera still) one step at a time.
struct SlotDriver {
  const Model& model;
  State* state;
  sim::Workspace ws;
  InputFrame frame;
  SlotDriver(const Model& m, State* s, const std::string& instrument) : model(m), state(s) {
    sim::BuildWorkspace(m, *s, &ws);
    frame.camera.pose = m.camera.initial_pose;
    frame.tools[0].instrument = m.FindInstrument(instrument);
    frame.tools[0].pose.orientation = Downward();
  }
  /// One step with the tool tip at `tip_mm`, jaw and buttons as given.
  void Step(const Vec3& tip_mm, double jaw, std::uint8_t buttons = 0) {
    frame.tools[0].pose.position_mm = tip_mm;
    frame.tools[0].jaw = jaw;
    frame.tools[0].buttons = buttons;
    sim::Step(model, frame, state, &ws);
  }
  /// Events of kind `kind` in the last step.
  std::vector<Event> Events(const std::string& kind) const {
    std::vector<Event> out;
    for (const Event& e : state->events)
      if (e.kind == kind) out.push_back(e);
    return out;
  }
};

}  // namespace arthrosim::testing
