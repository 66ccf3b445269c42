#include "arthrosim/io/scenario_loader.h"

#include <fmt/format.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <utility>
#include <vector>

#include "arthrosim/core/enum_names.h"
#include "arthrosim/core/error.h"
#include "arthrosim/core/hash.h"
#include "arthrosim/core/input_file.h"
#include "arthrosim/core/scope_aim.h"
#include "arthrosim/core/units.h"
#include "arthrosim/core/yaml_fields.h"
#include "arthrosim/mesh/mesh_io.h"
#include "arthrosim/mesh/mesh_validate.h"
#include "arthrosim/mesh/surface.h"
#include "arthrosim/mesh/surface_tissue.h"
#include "scenario_operations.h"
#include "scenario_ranges.h"

namespace arthrosim::io {
namespace {

namespace fs = std::filesystem;

// Gravity's length against ranges::kMaxGravityMmS2 (error) and the usual range (warning).
void CheckGravity(const YamlSection& root, const Vec3& gravity_mm_s2) {
  if (!root.Has("gravity")) return;
  const double g = gravity_mm_s2.norm();
  if (g > ranges::kMaxGravityMmS2) {
    root.Fail("gravity", fmt::format("its length must be <= {:g} mm/s^2 (10 g), got {:g}",
                                     ranges::kMaxGravityMmS2, g));
  }
  if (g > ranges::kUsualMaxGravityMmS2 || (g > 0 && g < ranges::kUsualMinGravityMmS2)) {
    root.reader().Warn(root.Get("gravity"), root.Field("gravity"),
                       fmt::format("{:g} mm/s^2 is outside the usual range [{:g}, {:g}] mm/s^2 "
                                   "(Earth: 9810; 0 for none): check the unit",
                                   g, ranges::kUsualMinGravityMmS2, ranges::kUsualMaxGravityMmS2));
  }
}

// The scenario's names of the solver choices.
constexpr EnumName<Integrator> kIntegrators[] = {{Integrator::kImplicitEuler, "implicit_euler"},
                                                 {Integrator::kArkode, "arkode"}};
constexpr EnumName<SystemProduct> kProducts[] = {{SystemProduct::kAssembled, "assembled"},
                                                 {SystemProduct::kMatrixFree, "matrix_free"}};
constexpr EnumName<Preconditioner> kPreconditioners[] = {
    {Preconditioner::kRestCholesky, "rest_cholesky"},
    {Preconditioner::kBlockJacobi, "block_jacobi"}};

// The value `table` names by the string at `key` (`fallback` when absent). Throws InputError
// ("expected a or b, got 'x'") for a string the table does not list.
template <class E, std::size_t N>
E ReadChoice(const YamlSection& s, const char* key, const EnumName<E> (&table)[N],
             const char* fallback) {
  const std::string name = s.String(key, fallback);
  if (const std::optional<E> value = ValueIn(table, name)) return *value;
  std::string expected;
  for (std::size_t i = 0; i < N; ++i) {
    expected += i == 0 ? "" : (i + 1 == N ? " or " : ", ");
    expected += table[i].name;
  }
  s.Fail(key, "expected " + expected + ", got '" + name + "'");
}

void ReadTimeAndSolver(const YamlSection& root, Model* m) {
  if (root.Has("time")) {
    YamlSection t(root.reader(), root.Get("time"), "time", {"dt", "duration"});
    m->options.dt_s = t.Quantity("dt", ranges::kTimeStep, 0.02);
    m->options.duration_s = t.Quantity("duration", ranges::kDuration, 1.0);
  }
  m->options.gravity_mm_s2 = root.Vector("gravity", m->options.gravity_mm_s2);
  CheckGravity(root, m->options.gravity_mm_s2);
  m->options.seed = static_cast<std::uint64_t>(root.Integer("seed", 1, 0));
  if (root.Has("solver")) {
    YamlSection s(root.reader(), root.Get("solver"), "solver",
                  {"integrator", "cg_max_iterations", "cg_tolerance", "product", "preconditioner",
                   "refactor_iterations", "refactor_lag_steps", "refactor_slack_iterations",
                   "divergence_speed", "divergence_max_substeps"});
    m->solver.integrator = ReadChoice(s, "integrator", kIntegrators, "implicit_euler");
    m->solver.cg_max_iterations =
        static_cast<int>(s.Integer("cg_max_iterations", 100, 1, ranges::kMaxIterations));
    m->solver.cg_tolerance = s.Positive("cg_tolerance", 1e-8);
    m->solver.product = ReadChoice(s, "product", kProducts, "assembled");
    m->solver.preconditioner = ReadChoice(s, "preconditioner", kPreconditioners, "rest_cholesky");
    m->solver.refactor_iterations = static_cast<int>(
        s.Integer("refactor_iterations", m->solver.refactor_iterations, 0, ranges::kMaxIterations));
    m->solver.refactor_lag_steps =
        static_cast<int>(s.Integer("refactor_lag_steps", m->solver.refactor_lag_steps, 1, 1000));
    m->solver.refactor_slack_iterations =
        static_cast<int>(s.Integer("refactor_slack_iterations", m->solver.refactor_slack_iterations,
                                   0, ranges::kMaxIterations));
    m->solver.divergence_speed_mm_s =
        s.Quantity("divergence_speed", ranges::kDivergenceSpeed, m->solver.divergence_speed_mm_s);
    m->solver.divergence_max_substeps = static_cast<int>(s.Integer(
        "divergence_max_substeps", m->solver.divergence_max_substeps, 1, ranges::kMaxPasses));
  }
  if (root.Has("output")) {
    YamlSection o(root.reader(), root.Get("output"), "output",
                  {"file", "every", "flush_interval", "checkpoint_every"});
    m->options.output_file = o.String("file", "run.h5");
    m->options.output_every_steps =
        static_cast<int>(o.Integer("every", 1, 1, ranges::kMaxOutputEvery));
    m->options.flush_interval_s = o.Quantity("flush_interval", ranges::kFlushInterval, 1.0);
    m->options.checkpoint_every_s =
        o.Quantity("checkpoint_every", ranges::kCheckpointInterval, m->options.checkpoint_every_s);
  }
}

// Optional `contact:` section: distances in mm, stiffnesses in N/mm (docs/scenario-format.md).
void ReadContact(const YamlSection& root, Model* m) {
  if (!root.Has("contact")) return;
  ContactOptions& c = m->contact;
  YamlSection s(root.reader(), root.Get("contact"), "contact",
                {"alarm_distance", "contact_distance", "max_depth", "thread_bone_reach",
                 "sweep_fraction", "max_substeps", "stiffness", "sharp_point_volume_contacts",
                 "tissue_tissue_contacts", "bone_tip_contacts"});
  c.alarm_distance_mm = s.Quantity("alarm_distance", ranges::kContactDistance, c.alarm_distance_mm);
  c.contact_distance_mm =
      s.Quantity("contact_distance", ranges::kContactDistance, c.contact_distance_mm);
  if (!(c.contact_distance_mm < c.alarm_distance_mm)) {
    root.reader().Fail(s.Has("contact_distance") ? s.Get("contact_distance") : s.node(),
                       s.Field("contact_distance"),
                       "must be < contact.alarm_distance (contacts must exist "
                       "before the gap they keep)");
  }
  c.max_depth_mm = s.Positive("max_depth", c.max_depth_mm);
  c.thread_bone_reach_mm = s.Positive("thread_bone_reach", c.thread_bone_reach_mm);
  c.sweep_fraction = s.Positive("sweep_fraction", c.sweep_fraction);
  if (c.sweep_fraction > 1) {
    root.reader().Fail(s.Get("sweep_fraction"), s.Field("sweep_fraction"),
                       "must be in (0, 1] (a larger sweep substep can tunnel)");
  }
  c.max_substeps =
      static_cast<int>(s.Integer("max_substeps", c.max_substeps, 1, ranges::kMaxPasses));
  if (c.max_substeps > 4096) {
    root.reader().Fail(s.Get("max_substeps"), s.Field("max_substeps"), "must be <= 4096");
  }
  c.sharp_point_volume_contacts =
      s.Bool("sharp_point_volume_contacts", c.sharp_point_volume_contacts);
  c.tissue_tissue_contacts = s.Bool("tissue_tissue_contacts", c.tissue_tissue_contacts);
  c.bone_tip_contacts = s.Bool("bone_tip_contacts", c.bone_tip_contacts);
  if (!s.Has("stiffness")) return;
  // The contact stiffnesses (N/mm) by their key under `stiffness:`.
  static constexpr std::pair<const char*, double ContactOptions::*> kStiffness[] = {
      {"tool_tissue", &ContactOptions::tool_tissue_stiffness_n_per_mm},
      {"tool_thread", &ContactOptions::tool_thread_stiffness_n_per_mm},
      {"tool_volume", &ContactOptions::tool_volume_stiffness_n_per_mm},
      {"thread_tissue", &ContactOptions::thread_tissue_stiffness_n_per_mm},
      {"tissue_tissue", &ContactOptions::tissue_tissue_stiffness_n_per_mm},
      {"bone", &ContactOptions::bone_stiffness_n_per_mm},
      {"thread_bone", &ContactOptions::thread_bone_stiffness_n_per_mm},
      {"tool_bone", &ContactOptions::tool_bone_stiffness_n_per_mm}};
  std::vector<const char*> keys;
  for (const auto& [key, member] : kStiffness) keys.push_back(key);
  const YamlSection k(root.reader(), s.Get("stiffness"), s.Field("stiffness"), keys);
  for (const auto& [key, member] : kStiffness)
    c.*member = k.Quantity(key, ranges::kContactStiffness, c.*member);
}

// Optional `thread_solver:` section: the suture solver's settings (docs/scenario-format.md).
void ReadThreadSolver(const YamlSection& root, Model* m) {
  if (!root.Has("thread_solver")) return;
  ThreadSolverOptions& t = m->thread_solver;
  YamlSection s(
      root.reader(), root.Get("thread_solver"), "thread_solver",
      {"contact_stiffness", "contact_margin_factor", "max_newton_iterations", "max_substep_levels",
       "max_active_set_passes", "max_strain", "strain_limit_passes", "newton_tolerance",
       "max_ccd_rounds", "ccd_samples", "ccd_close_fraction", "crossing_tolerance",
       "compression_stiffness_fraction", "speed_barrier_stiffness", "exclusion_factor"});
  t.contact_stiffness_n_per_mm = s.Positive("contact_stiffness", t.contact_stiffness_n_per_mm);
  t.contact_margin_factor = s.NonNegative("contact_margin_factor", t.contact_margin_factor);
  t.max_newton_iterations = static_cast<int>(
      s.Integer("max_newton_iterations", t.max_newton_iterations, 1, ranges::kMaxPasses));
  t.max_substep_levels = static_cast<int>(
      s.Integer("max_substep_levels", t.max_substep_levels, 0, kMaxThreadSubstepLevels));
  t.max_active_set_passes = static_cast<int>(
      s.Integer("max_active_set_passes", t.max_active_set_passes, 1, ranges::kMaxPasses));
  t.max_strain = s.Positive("max_strain", t.max_strain);
  t.strain_limit_passes = static_cast<int>(
      s.Integer("strain_limit_passes", t.strain_limit_passes, 1, ranges::kMaxPasses));
  t.newton_tolerance_mm = s.Positive("newton_tolerance", t.newton_tolerance_mm);
  t.max_ccd_rounds =
      static_cast<int>(s.Integer("max_ccd_rounds", t.max_ccd_rounds, 0, ranges::kMaxPasses));
  t.ccd_samples = static_cast<int>(s.Integer("ccd_samples", t.ccd_samples, 1, ranges::kMaxPasses));
  t.ccd_close_fraction = s.NonNegative("ccd_close_fraction", t.ccd_close_fraction);
  t.crossing_tolerance_mm = s.Positive("crossing_tolerance", t.crossing_tolerance_mm);
  t.compression_stiffness_fraction =
      s.NonNegative("compression_stiffness_fraction", t.compression_stiffness_fraction);
  if (t.compression_stiffness_fraction > 1) {
    s.Fail("compression_stiffness_fraction",
           "must be in [0, 1] (a fraction of the stretch stiffness)");
  }
  t.speed_barrier_stiffness_n_per_mm =
      s.Positive("speed_barrier_stiffness", t.speed_barrier_stiffness_n_per_mm);
  t.exclusion_factor = s.NonNegative("exclusion_factor", t.exclusion_factor);
}

// Optional `haptics:` section: the handle-proxy coupling and the force clamp (docs/haptics.md).
void ReadHaptics(const YamlSection& root, Model* m) {
  if (!root.Has("haptics")) return;
  HapticsOptions& h = m->haptics;
  YamlSection s(root.reader(), root.Get("haptics"), "haptics",
                {"proxy", "slide", "coupling_stiffness_n_per_mm", "coupling_damping_n_s_per_mm",
                 "max_force_n", "trapped_gap_mm", "trapped_friction"});
  h.proxy = s.Bool("proxy", h.proxy);
  h.slide = s.Bool("slide", h.slide);
  h.coupling_stiffness_n_per_mm =
      s.Positive("coupling_stiffness_n_per_mm", h.coupling_stiffness_n_per_mm);
  h.coupling_damping_n_s_per_mm =
      s.NonNegative("coupling_damping_n_s_per_mm", h.coupling_damping_n_s_per_mm);
  h.max_force_n = s.Quantity("max_force_n", ranges::kHapticMaxForce, h.max_force_n);
  h.trapped_gap_mm = s.NonNegative("trapped_gap_mm", h.trapped_gap_mm);
  h.trapped_friction = s.NonNegative("trapped_friction", h.trapped_friction);
}

void ReadMaterials(const YamlSection& root, Model* m) {
  const YAML::Node materials = root.Required("materials");
  if (!materials.IsMap())
    root.reader().Fail(materials, "materials", "expected a mapping name -> material");
  for (auto it = materials.begin(); it != materials.end(); ++it) {
    Material mat;
    mat.name = root.reader().Scalar(it->first, "materials");
    YamlSection s(
        root.reader(), it->second, "materials." + mat.name,
        {"young_modulus", "poisson_ratio", "density", "rayleigh_mass", "rayleigh_stiffness"});
    mat.young_modulus_pa = s.Quantity("young_modulus", ranges::kYoungModulus);
    mat.poisson_ratio = s.Number("poisson_ratio");
    if (mat.poisson_ratio < 0 || mat.poisson_ratio >= 0.5) {
      root.reader().Fail(s.Get("poisson_ratio"), s.Field("poisson_ratio"),
                         "must be in [0, 0.5), got " + s.Get("poisson_ratio").Scalar());
    }
    mat.density_kg_m3 = s.Quantity("density", ranges::kDensity);
    mat.rayleigh_mass = s.Quantity("rayleigh_mass", ranges::kRayleighMass, 0);
    mat.rayleigh_stiffness = s.Quantity("rayleigh_stiffness", ranges::kRayleighStiffness, 0);
    m->materials.push_back(mat);
  }
}

// Runs read (which reads the mesh of body section s); a fault in the mesh file is rethrown
// naming the scenario line and field that referenced the mesh, then the mesh's own file, line
// and field.
template <class Read>
void WithMeshContext(const YamlSection& s, const Read& read) {
  try {
    read();
  } catch (const InputError& e) {
    if (e.file() == s.reader().file()) throw;  // already the scenario's own error
    s.Fail("mesh", std::string("in the mesh: ") + e.what());
  }
}

// Resolves a mesh path relative to the scenario and checks it is a regular file (a device such
// as /dev/zero or a FIFO would never finish reading).
std::string MeshPath(const YamlSection& s, const fs::path& base_dir) {
  const std::string rel = s.String("mesh");
  const fs::path p = base_dir / rel;
  if (!fs::is_regular_file(p)) {
    std::error_code ec;
    s.reader().Fail(s.Get("mesh"), s.Field("mesh"),
                    fs::exists(p, ec) ? "mesh is not a regular file (a directory, a device or a "
                                        "FIFO): " +
                                            p.string()
                                      : "mesh file not found: " + p.string());
  }
  return p.string();
}

void ReadThreadBlock(const YamlSection& body, ThreadModel* t) {
  YamlSection s(body.reader(), body.Required("thread"), body.Field("thread"),
                {"start", "end", "nodes", "diameter", "density", "stretch_stiffness",
                 "bend_stiffness", "damping", "max_speed", "self_collision", "fixed_nodes"});
  const Vec3 start = s.Vector("start");
  const Vec3 end = s.Vector("end");
  if (!s.Has("nodes")) s.Required("nodes");
  const auto n = s.Integer("nodes", 0, 2, ranges::kMaxThreadNodes);
  if ((end - start).norm() <= 0)
    s.reader().Fail(s.Get("end"), s.Field("end"), "must differ from start");
  t->initial.nodes.resize(3, n);
  for (std::int64_t i = 0; i < n; ++i) {
    t->initial.nodes.col(i) = start + (end - start) * (static_cast<double>(i) / double(n - 1));
    if (i > 0) t->initial.edges.push_back({std::int32_t(i - 1), std::int32_t(i)});
  }
  t->diameter_mm = s.Quantity("diameter", ranges::kThreadDiameter, 0.55);
  t->density_kg_m3 = s.Quantity("density", ranges::kDensity, 1300);
  t->stretch_stiffness_n = s.Quantity("stretch_stiffness", ranges::kThreadStretchStiffness, 5000);
  t->bend_stiffness_n_mm2 = s.NonNegative("bend_stiffness", 0);
  t->damping_per_s = s.NonNegative("damping", 0);
  t->max_speed_mm_s = s.Quantity("max_speed", ranges::kThreadMaxSpeed, 500);
  t->self_collision = s.Bool("self_collision", true);
  const YAML::Node fixed = s.Sequence("fixed_nodes", false);
  for (std::size_t i = 0; i < fixed.size(); ++i) {
    const double v = s.reader().Number(fixed[i], IndexedField(s.Field("fixed_nodes"), i));
    if (v != std::floor(v) || v < 0 || v >= double(n)) {
      s.reader().Fail(fixed[i], IndexedField(s.Field("fixed_nodes"), i),
                      "expected a node index in [0, " + std::to_string(n - 1) + "]");
    }
    t->fixed_nodes.push_back(static_cast<std::int32_t>(v));
  }
  std::sort(t->fixed_nodes.begin(), t->fixed_nodes.end());
  t->fixed_nodes.erase(std::unique(t->fixed_nodes.begin(), t->fixed_nodes.end()),
                       t->fixed_nodes.end());
}

// A rigid body's `tissues:` list: names of triangle groups of its mesh file that are a tissue
// of their own; labels every surface triangle (first listed tissue wins, -1 for bone).
void ReadBoneTissues(const YamlSection& s, const mesh::MeshData& data, BoneModel* b) {
  if (!s.Has("tissues")) return;
  const YAML::Node list = s.Sequence("tissues", true);
  if (list.size() == 0) s.Fail("tissues", "expected at least one surface group name");
  if (list.size() > 127) s.Fail("tissues", "at most 127 tissues per bone");
  // (data.surface was moved into b->surface; the groups index its triangles)
  if (data.tri_physical.size() != b->surface.tris.size())
    s.Fail("tissues", "the mesh has no triangle groups (a surface mesh with named groups)");
  b->tri_tissue.assign(b->surface.tris.size(), mesh::kBoneTissue);
  for (std::size_t i = 0; i < list.size(); ++i) {
    const std::string field = IndexedField(s.Field("tissues"), i);
    const std::string name = s.reader().Scalar(list[i], field);
    if (std::find(b->tissues.begin(), b->tissues.end(), name) != b->tissues.end())
      s.reader().Fail(list[i], field, "tissue '" + name + "' listed twice");
    const auto group =
        std::find_if(data.groups.begin(), data.groups.end(),
                     [&](const mesh::PhysicalGroup& g) { return g.dim == 2 && g.name == name; });
    if (group == data.groups.end()) {
      std::string known;
      for (const mesh::PhysicalGroup& g : data.groups)
        if (g.dim == 2 && !g.name.empty()) known += (known.empty() ? "" : ", ") + g.name;
      s.reader().Fail(list[i], field,
                      "the mesh has no triangle group '" + name +
                          "' (it has: " + (known.empty() ? "none" : known) + ")");
    }
    if (group->elements.empty()) s.reader().Fail(list[i], field, "group '" + name + "' is empty");
    const auto label = static_cast<std::int8_t>(b->tissues.size());
    b->tissues.push_back(name);
    for (std::int32_t t : group->elements) {
      if (t < 0 || static_cast<std::size_t>(t) >= b->tri_tissue.size()) continue;
      std::int8_t& l = b->tri_tissue[static_cast<std::size_t>(t)];
      if (l == mesh::kBoneTissue) l = label;
    }
  }
}

// A body's `fixed:` list, resolved once regions are known.
struct PendingFixed {
  YAML::Node list;
  std::string field;
  std::string body;
  std::vector<std::int32_t>* nodes = nullptr;  // where the resolved node indices go
};

// Body entries are read in two passes: geometry first (here), fixed regions after regions.
void ReadBodies(const YamlSection& root, const fs::path& base_dir, Model* m,
                std::vector<PendingFixed>* pending) {
  const YAML::Node bodies = root.Sequence("bodies", true);
  std::set<std::string> names;
  for (std::size_t i = 0; i < bodies.size(); ++i) {
    const std::string field = IndexedField("bodies", i);
    YamlSection s(root.reader(), bodies[i], field,
                  {"name", "kind", "mesh", "material", "fixed", "hardness", "thread", "tissues"});
    const std::string name = s.String("name");
    if (!names.insert(name).second)
      root.reader().Fail(s.Get("name"), s.Field("name"), "duplicate body name '" + name + "'");
    const std::string kind = s.String("kind");
    if (kind == "soft") {
      SoftBodyModel b;
      b.name = name;
      b.mesh_file = s.String("mesh");
      WithMeshContext(s, [&] {
        b.rest_mesh = mesh::ReadTetMesh(MeshPath(s, base_dir));
        mesh::OrientAndCheck(&b.rest_mesh, MeshPath(s, base_dir));
      });
      if (b.rest_mesh.tets.empty())
        root.reader().Fail(s.Get("mesh"), s.Field("mesh"), "soft body mesh has no tetrahedra");
      const std::string mat = s.String("material");
      auto found = std::find_if(m->materials.begin(), m->materials.end(),
                                [&](const Material& x) { return x.name == mat; });
      if (found == m->materials.end())
        root.reader().Fail(s.Get("material"), s.Field("material"),
                           "unknown material '" + mat + "'");
      b.material = *found;
      m->soft_bodies.push_back(std::move(b));
    } else if (kind == "rigid") {
      BoneModel b;
      b.name = name;
      b.mesh_file = s.String("mesh");
      mesh::MeshData data;
      WithMeshContext(s, [&] { data = mesh::ReadMesh(MeshPath(s, base_dir)); });
      if (!data.surface.tris.empty()) {
        b.surface = std::move(data.surface);
      } else if (!data.volume.tets.empty()) {
        b.surface = mesh::BoundaryTriMesh(data.volume);
      }
      if (b.surface.tris.empty())
        root.reader().Fail(s.Get("mesh"), s.Field("mesh"), "rigid body mesh has no triangles");
      b.hardness = s.Quantity("hardness", ranges::kBoneHardness, 1.0);
      ReadBoneTissues(s, data, &b);
      m->bones.push_back(std::move(b));
    } else if (kind == "thread") {
      ThreadModel t;
      t.name = name;
      ReadThreadBlock(s, &t);
      m->threads.push_back(std::move(t));
    } else {
      root.reader().Fail(s.Get("kind"), s.Field("kind"),
                         "expected soft, rigid or thread, got '" + kind + "'");
    }
    if (kind != "thread" && s.Has("thread"))
      root.reader().Fail(s.Get("thread"), s.Field("thread"),
                         "only thread bodies take a thread block");
    if (kind != "rigid" && s.Has("tissues"))
      root.reader().Fail(s.Get("tissues"), s.Field("tissues"),
                         "only rigid bodies take tissues (surface groups of their mesh)");
    if (kind != "soft" && s.Has("material"))
      root.reader().Fail(s.Get("material"), s.Field("material"),
                         "only soft bodies take a material");
    if (s.Has("fixed")) {
      if (kind == "rigid")
        root.reader().Fail(s.Get("fixed"), s.Field("fixed"), "rigid bodies are fixed already");
      pending->push_back({s.Get("fixed"), s.Field("fixed"), name, nullptr});
    }
  }
  // Vectors are complete now, so pointers into them stay valid.
  for (PendingFixed& p : *pending) {
    if (int i = m->FindSoftBody(p.body); i >= 0) p.nodes = &m->soft_bodies[i].fixed_nodes;
    if (int i = m->FindThread(p.body); i >= 0) p.nodes = &m->threads[i].fixed_nodes;
  }
}

// The node positions of a body by name, for regions; nullptr if no such body.
const Points* BodyNodes(const Model& m, const std::string& name) {
  if (int i = m.FindSoftBody(name); i >= 0) return &m.soft_bodies[i].rest_mesh.nodes;
  if (int i = m.FindBone(name); i >= 0) return &m.bones[i].surface.nodes;
  if (int i = m.FindThread(name); i >= 0) return &m.threads[i].initial.nodes;
  return nullptr;
}

void ReadRegionsAndLandmarks(const YamlSection& root, Model* m) {
  const YAML::Node regions = root.Sequence("regions", false);
  for (std::size_t i = 0; i < regions.size(); ++i) {
    YamlSection s(root.reader(), regions[i], IndexedField("regions", i), {"name", "body", "box"});
    Region r;
    r.name = s.String("name");
    if (m->FindRegion(r.name) >= 0)
      root.reader().Fail(s.Get("name"), s.Field("name"), "duplicate region name");
    r.body = s.String("body");
    const Points* nodes = BodyNodes(*m, r.body);
    if (!nodes) root.reader().Fail(s.Get("body"), s.Field("body"), "unknown body '" + r.body + "'");
    YamlSection box(root.reader(), s.Required("box"), s.Field("box"), {"min", "max"});
    r.box_min_mm = box.Vector("min");
    r.box_max_mm = box.Vector("max");
    if ((r.box_max_mm.array() < r.box_min_mm.array()).any())
      root.reader().Fail(box.Get("max"), box.Field("max"), "max must be >= min in every axis");
    for (Eigen::Index n = 0; n < nodes->cols(); ++n) {
      const Vec3 p = nodes->col(n);
      if ((p.array() >= r.box_min_mm.array()).all() && (p.array() <= r.box_max_mm.array()).all()) {
        r.nodes.push_back(static_cast<std::int32_t>(n));
      }
    }
    if (r.nodes.empty())
      root.reader().Fail(s.Get("box"), s.Field("box"),
                         "region '" + r.name + "' contains no node of body '" + r.body + "'");
    m->regions.push_back(std::move(r));
  }
  const YAML::Node landmarks = root.Sequence("landmarks", false);
  for (std::size_t i = 0; i < landmarks.size(); ++i) {
    YamlSection s(root.reader(), landmarks[i], IndexedField("landmarks", i),
                  {"name", "body", "position"});
    Landmark l;
    l.name = s.String("name");
    if (m->FindLandmark(l.name) >= 0)
      root.reader().Fail(s.Get("name"), s.Field("name"), "duplicate landmark name");
    l.body = s.String("body", "");
    if (!l.body.empty() && !BodyNodes(*m, l.body))
      root.reader().Fail(s.Get("body"), s.Field("body"), "unknown body '" + l.body + "'");
    l.position_mm = s.Vector("position");
    m->landmarks.push_back(l);
  }
}

// Resolves each body's `fixed: [region, ...]` into sorted unique node indices.
void ResolveFixed(const YamlReader& ctx, const Model& m, const std::vector<PendingFixed>& pending) {
  for (const PendingFixed& p : pending) {
    if (!p.list.IsSequence()) ctx.Fail(p.list, p.field, "expected a list of region names");
    for (std::size_t k = 0; k < p.list.size(); ++k) {
      const YAML::Node item = p.list[k];
      const std::string field = IndexedField(p.field, k);
      if (!item.IsScalar()) ctx.Fail(item, field, "expected a region name");
      const int r = m.FindRegion(item.Scalar());
      if (r < 0) ctx.Fail(item, field, "unknown region '" + item.Scalar() + "'");
      if (m.regions[r].body != p.body) {
        ctx.Fail(item, field,
                 "region '" + item.Scalar() + "' belongs to body '" + m.regions[r].body +
                     "', not '" + p.body + "'");
      }
      p.nodes->insert(p.nodes->end(), m.regions[r].nodes.begin(), m.regions[r].nodes.end());
    }
    std::sort(p.nodes->begin(), p.nodes->end());
    p.nodes->erase(std::unique(p.nodes->begin(), p.nodes->end()), p.nodes->end());
  }
}

void ReadJoinsAndPortals(const YamlSection& root, Model* m) {
  const YAML::Node joins = root.Sequence("joins", false);
  for (std::size_t i = 0; i < joins.size(); ++i) {
    YamlSection s(root.reader(), joins[i], IndexedField("joins", i), {"a", "b", "tolerance"});
    Join j{s.String("a"), s.String("b"), s.Positive("tolerance", 1e-6)};
    for (const char* key : {"a", "b"}) {
      const std::string& body = key[0] == 'a' ? j.body_a : j.body_b;
      if (m->FindSoftBody(body) < 0)
        root.reader().Fail(s.Get(key), s.Field(key),
                           "expected the name of a soft body, got '" + body + "'");
    }
    if (j.body_a == j.body_b)
      root.reader().Fail(s.Get("b"), s.Field("b"), "a body cannot be joined to itself");
    m->joins.push_back(j);
  }
  const YAML::Node portals = root.Sequence("portals", false);
  for (std::size_t i = 0; i < portals.size(); ++i) {
    YamlSection s(root.reader(), portals[i], IndexedField("portals", i), {"name", "position"});
    Portal p{s.String("name"), s.Vector("position")};
    if (m->FindPortal(p.name) >= 0)
      root.reader().Fail(s.Get("name"), s.Field("name"), "duplicate portal name");
    m->portals.push_back(p);
  }
}

std::string CheckPortal(const YamlSection& s, const Model& m, const std::string& fallback) {
  const std::string portal = s.String("portal", fallback);
  if (m.FindPortal(portal) < 0)
    s.reader().Fail(s.Has("portal") ? s.Get("portal") : s.node(), s.Field("portal"),
                    "unknown portal '" + portal + "'");
  return portal;
}

void ReadInstruments(const YamlSection& root, Model* m) {
  const YAML::Node list = root.Sequence("instruments", false);
  for (std::size_t i = 0; i < list.size(); ++i) {
    YamlSection s(
        root.reader(), list[i], IndexedField("instruments", i),
        {"name", "kind", "portal", "shaft_diameter", "shaft_length", "tip_length", "tip_radius"});
    InstrumentModel in;
    in.name = s.String("name");
    if (m->FindInstrument(in.name) >= 0)
      root.reader().Fail(s.Get("name"), s.Field("name"), "duplicate instrument name");
    const std::string kind = s.String("kind");
    const auto parsed = ParseInstrumentKind(kind);
    if (!parsed) {
      root.reader().Fail(
          s.Get("kind"), s.Field("kind"),
          "unknown instrument kind '" + kind +
              "' (expected scissors, cutter, burr, shaver, electrocautery, awl, retriever, "
              "grasper, scorpion_needle, knot_pusher or hook)");
    }
    in.kind = *parsed;
    in.portal = CheckPortal(s, *m, "");
    in.shaft_diameter_mm = s.Quantity("shaft_diameter", ranges::kShaftDiameter, 4.5);
    in.shaft_length_mm = s.Positive("shaft_length", 150);
    in.tip_length_mm = s.Positive("tip_length", 8);
    in.tip_radius_mm = s.Positive("tip_radius", 2);
    m->instruments.push_back(in);
  }
}

void ReadCamera(const YamlSection& root, Model* m) {
  CameraModel& c = m->camera;
  if (!root.Has("camera")) {
    c.initial_pose = Pose{};
    return;
  }
  YamlSection s(root.reader(), root.Get("camera"), "camera",
                {"portal", "fov", "lens_angle", "diameter", "near", "far", "position", "look_at"});
  c.portal = s.Has("portal") ? CheckPortal(s, *m, "") : c.portal;
  c.fov_deg = s.Positive("fov", 105);
  if (c.fov_deg >= 180) root.reader().Fail(s.Get("fov"), s.Field("fov"), "must be < 180 degrees");
  c.lens_angle_deg = s.NonNegative("lens_angle", 30);
  if (c.lens_angle_deg >= 90)
    root.reader().Fail(s.Get("lens_angle"), s.Field("lens_angle"), "must be < 90 degrees");
  c.diameter_mm = s.Positive("diameter", 4.0);
  c.near_mm = s.Positive("near", 1.0);
  c.far_mm = s.Positive("far", 100.0);
  if (c.far_mm <= c.near_mm) root.reader().Fail(s.Get("far"), s.Field("far"), "must be > near");
  const Vec3 eye = s.Vector("position", Vec3(0, 0, 0));
  const Vec3 target = s.Vector("look_at", eye + Vec3::UnitX());
  if ((target - eye).norm() <= 0)
    root.reader().Fail(s.Get("look_at"), s.Field("look_at"), "must differ from position");
  // the oblique view, not the shaft, looks at the target (the image centre)
  c.initial_pose = Pose{eye, AimScopeView(eye, target, c.lens_angle_deg * units::kDegToRad)};
}

// Hands the reader's warnings to the caller, or prints them to stderr when it takes none.
void ReportWarnings(const std::vector<std::string>& found, std::vector<std::string>* warnings) {
  if (warnings != nullptr) {
    warnings->insert(warnings->end(), found.begin(), found.end());
    return;
  }
  for (const std::string& w : found) std::fprintf(stderr, "warning: %s\n", w.c_str());
}

}  // namespace

Model LoadScenarioFromText(const std::string& text, const std::string& path,
                           std::vector<std::string>* warnings) {
  const YamlReader ctx(path);
  const YAML::Node doc = ParseYaml(text, path);
  if (!doc.IsMap()) throw InputError(path, 1, "", "expected a YAML mapping at the top level");
  YamlSection root(ctx, doc, "",
                   {"name", "seed", "time", "gravity", "solver", "output", "contact", "operations",
                    "thread_solver", "haptics", "materials", "bodies", "joins", "portals",
                    "instruments", "camera", "landmarks", "regions"});
  Model m;
  m.scenario_path = path;
  m.scenario_text = text;
  m.scenario_sha256 = Sha256Hex(text);
  m.name = root.String("name");
  ReadTimeAndSolver(root, &m);
  ReadContact(root, &m);
  ReadThreadSolver(root, &m);
  ReadHaptics(root, &m);
  ReadMaterials(root, &m);
  std::vector<PendingFixed> pending_fixed;
  ReadBodies(root, fs::path(path).parent_path(), &m, &pending_fixed);
  ReadRegionsAndLandmarks(root, &m);
  ResolveFixed(ctx, m, pending_fixed);
  ReadJoinsAndPortals(root, &m);
  ReadInstruments(root, &m);
  ReadCamera(root, &m);
  ReadOperations(root, &m);  // last: operations name bodies (the anchor's sutures)
  ReportWarnings(ctx.warnings(), warnings);
  return m;
}

Model LoadScenario(const std::string& path, std::vector<std::string>* warnings) {
  return LoadScenarioFromText(ReadInputFile(path, "", "cannot open scenario file"), path, warnings);
}

}  // namespace arthrosim::io
