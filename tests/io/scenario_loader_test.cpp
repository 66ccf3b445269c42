#include "arthrosim/io/scenario_loader.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "arthrosim/core/error.h"
#include "arthrosim/core/scope_aim.h"
#include "arthrosim/core/units.h"

namespace arthrosim::io {
namespace {

namespace fs = std::filesystem;

// A scratch folder with a one-tet VTK mesh and a triangle surface, for scenarios to point at.
class ScenarioLoaderTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ =
        fs::temp_directory_path() /
        ("arthrosim_scenario_" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()) +
         "_" + ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir_);
    Write("block.vtk",
          "# vtk DataFile Version 3.0\nblock\nASCII\nDATASET UNSTRUCTURED_GRID\n"
          "POINTS 5 double\n0 0 0\n10 0 0\n0 10 0\n0 0 10\n10 10 10\n"
          "CELLS 2 10\n4 0 1 2 3\n4 1 2 3 4\nCELL_TYPES 2\n10\n10\n");
    Write("bone.obj",
          "v 0 0 0\nv 10 0 0\nv 0 10 0\nv 0 0 10\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n");
  }
  void TearDown() override { fs::remove_all(dir_); }

  void Write(const std::string& name, const std::string& text) {
    std::ofstream(dir_ / name) << text;
  }
  std::string Path() const { return (dir_ / "scene.yaml").string(); }

  static std::string Valid() {
    return R"(name: test
seed: 7
time: {dt: 0.01, duration: 0.5}
materials:
  muscle: {young_modulus: 25000, poisson_ratio: 0.45, density: 1060, rayleigh_mass: 0.1}
bodies:
  - name: block
    kind: soft
    mesh: block.vtk
    material: muscle
    fixed: [base]
  - name: bone
    kind: rigid
    mesh: bone.obj
  - name: suture
    kind: thread
    thread: {start: [0, 0, 20], end: [30, 0, 20], nodes: 31, fixed_nodes: [0]}
regions:
  - {name: base, body: block, box: {min: [-1, -1, -1], max: [11, 11, 0.5]}}
portals:
  - {name: lateral, position: [50, 0, 0]}
instruments:
  - {name: grasper, kind: grasper, portal: lateral}
landmarks:
  - {name: tip, body: block, position: [0, 0, 10]}
camera: {portal: lateral, position: [40, 0, 0], look_at: [0, 0, 0]}
)";
  }

  // Loads `text` expecting an InputError; returns it.
  InputError LoadError(const std::string& text) {
    try {
      LoadScenarioFromText(text, Path());
    } catch (const InputError& e) {
      return e;
    }
    ADD_FAILURE() << "expected an InputError for:\n" << text;
    return InputError("", 0, "", "");
  }

  // Replaces the first occurrence of `from` in the valid scenario.
  static std::string Edit(const std::string& from, const std::string& to) {
    std::string s = Valid();
    const auto at = s.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    return s.replace(at, from.size(), to);
  }

  fs::path dir_;
};

TEST_F(ScenarioLoaderTest, LoadsAValidScenario) {
  const Model m = LoadScenarioFromText(Valid(), Path());
  EXPECT_EQ(m.name, "test");
  EXPECT_EQ(m.options.seed, 7u);
  EXPECT_DOUBLE_EQ(m.options.dt_s, 0.01);
  ASSERT_EQ(m.soft_bodies.size(), 1u);
  EXPECT_EQ(m.soft_bodies[0].rest_mesh.tets.size(), 2u);
  EXPECT_EQ(m.soft_bodies[0].fixed_nodes, (std::vector<std::int32_t>{0, 1, 2}));
  EXPECT_DOUBLE_EQ(m.soft_bodies[0].material.young_modulus_pa, 25000);
  ASSERT_EQ(m.bones.size(), 1u);
  EXPECT_EQ(m.bones[0].surface.tris.size(), 4u);
  ASSERT_EQ(m.threads.size(), 1u);
  EXPECT_EQ(m.threads[0].initial.nodes.cols(), 31);
  EXPECT_DOUBLE_EQ(m.threads[0].initial.nodes(0, 30), 30.0);
  EXPECT_EQ(m.threads[0].fixed_nodes, std::vector<std::int32_t>{0});
  EXPECT_EQ(m.instruments[0].kind, InstrumentKind::kGrasper);
  EXPECT_EQ(m.FindLandmark("tip"), 0);
  // The camera looks from (40,0,0) toward the origin: its oblique view (not its shaft, +z)
  // points along -x of the world, the shaft lens_angle away from it.
  const Vec3 forward = m.camera.initial_pose.orientation *
                       ScopeViewDirectionLocal(m.camera.lens_angle_deg * units::kDegToRad);
  EXPECT_NEAR((forward - Vec3(-1, 0, 0)).norm(), 0, 1e-12);
  EXPECT_NEAR((m.camera.initial_pose.orientation * Vec3::UnitZ()).dot(Vec3(-1, 0, 0)),
              std::cos(m.camera.lens_angle_deg * units::kDegToRad), 1e-12);
  EXPECT_EQ(m.scenario_sha256.size(), 64u);
}

TEST_F(ScenarioLoaderTest, UnknownKeyNamesFileLineAndField) {
  const InputError e = LoadError(Edit("seed: 7", "seed: 7\nsede: 8"));
  EXPECT_EQ(e.file(), Path());
  EXPECT_EQ(e.line(), 3);
  EXPECT_EQ(e.field(), "sede");
}

TEST_F(ScenarioLoaderTest, OperationsThresholdsAreCheckedKeys) {
  const Model m =
      LoadScenarioFromText(Edit("seed: 7",
                                "seed: 7\noperations: {grasper: {dist_limit: 3}, "
                                "scorpion_needle: {dist_limit_1: 4, nodes_through: 4}}"),
                           Path());
  EXPECT_EQ(m.operations.grasper.dist_limit_mm, 3.0);
  EXPECT_EQ(m.operations.retriever.dist_limit_mm, 2.0);  // the paper's 0.2 as mm
  EXPECT_EQ(m.operations.scorpion_needle.dist_limit_1_mm, 4.0);
  EXPECT_EQ(m.operations.scorpion_needle.dist_limit_2_mm, 2.0);
  EXPECT_EQ(m.operations.scorpion_needle.nodes_through, 4);
  const InputError typo =
      LoadError(Edit("seed: 7", "seed: 7\noperations: {grasper: {dist_limt: 3}}"));
  EXPECT_EQ(typo.field(), "operations.grasper.dist_limt");
  EXPECT_EQ(typo.line(), 3);
  const InputError negative =
      LoadError(Edit("seed: 7", "seed: 7\noperations: {retriever: {dist_limit: -1}}"));
  EXPECT_EQ(negative.field(), "operations.retriever.dist_limit");
}

// Scissors mode: remove (the default) or split; anything else is an error naming the field.
TEST_F(ScenarioLoaderTest, ScissorsModeIsRemoveOrSplit) {
  EXPECT_EQ(LoadScenarioFromText(Edit("seed: 7", "seed: 7"), Path()).operations.scissors.mode,
            CutMode::kRemove);  // the default
  EXPECT_EQ(LoadScenarioFromText(Edit("seed: 7", "seed: 7\noperations: {scissors: {mode: remove}}"),
                                 Path())
                .operations.scissors.mode,
            CutMode::kRemove);
  EXPECT_EQ(LoadScenarioFromText(Edit("seed: 7", "seed: 7\noperations: {scissors: {mode: split}}"),
                                 Path())
                .operations.scissors.mode,
            CutMode::kSplit);
  for (const char* mode : {"slice", "Split", ""}) {
    const InputError e = LoadError(
        Edit("seed: 7", std::string("seed: 7\noperations: {scissors: {mode: ") + mode + "}}"));
    EXPECT_EQ(e.field(), "operations.scissors.mode") << mode;
    EXPECT_EQ(e.line(), 3) << mode;
  }
}

TEST_F(ScenarioLoaderTest, NestedUnknownKeyIsAnError) {
  const InputError e = LoadError(Edit("rayleigh_mass: 0.1", "rayleigh_mas: 0.1"));
  EXPECT_EQ(e.field(), "materials.muscle.rayleigh_mas");
  EXPECT_EQ(e.line(), 5);
}

TEST_F(ScenarioLoaderTest, MissingRequiredField) {
  const InputError e = LoadError(Edit("density: 1060, ", ""));
  EXPECT_EQ(e.field(), "materials.muscle.density");
  EXPECT_NE(std::string(e.what()).find("missing"), std::string::npos);
}

TEST_F(ScenarioLoaderTest, WrongType) {
  const InputError e = LoadError(Edit("young_modulus: 25000", "young_modulus: soft"));
  EXPECT_EQ(e.field(), "materials.muscle.young_modulus");
  EXPECT_EQ(e.line(), 5);
}

TEST_F(ScenarioLoaderTest, NonPhysicalValues) {
  EXPECT_EQ(LoadError(Edit("young_modulus: 25000", "young_modulus: 0")).field(),
            "materials.muscle.young_modulus");
  EXPECT_EQ(LoadError(Edit("young_modulus: 25000", "young_modulus: -5")).field(),
            "materials.muscle.young_modulus");
  EXPECT_EQ(LoadError(Edit("poisson_ratio: 0.45", "poisson_ratio: 0.5")).field(),
            "materials.muscle.poisson_ratio");
  EXPECT_EQ(LoadError(Edit("poisson_ratio: 0.45", "poisson_ratio: -0.1")).field(),
            "materials.muscle.poisson_ratio");
  EXPECT_EQ(LoadError(Edit("dt: 0.01", "dt: 0")).field(), "time.dt");
  EXPECT_EQ(LoadError(Edit("dt: 0.01", "dt: -0.02")).field(), "time.dt");
  EXPECT_EQ(LoadError(Edit("dt: 0.01", "dt: .nan")).field(), "time.dt");
}

TEST_F(ScenarioLoaderTest, MissingMeshFile) {
  const InputError e = LoadError(Edit("mesh: block.vtk", "mesh: nowhere.vtk"));
  EXPECT_EQ(e.field(), "bodies[0].mesh");
  EXPECT_EQ(e.line(), 9);
  EXPECT_NE(std::string(e.what()).find("nowhere.vtk"), std::string::npos);
}

TEST_F(ScenarioLoaderTest, UnknownReferences) {
  EXPECT_EQ(LoadError(Edit("material: muscle", "material: bone")).field(), "bodies[0].material");
  EXPECT_EQ(LoadError(Edit("fixed: [base]", "fixed: [top]")).field(), "bodies[0].fixed[0]");
  EXPECT_EQ(LoadError(Edit("kind: grasper", "kind: spoon")).field(), "instruments[0].kind");
  EXPECT_EQ(LoadError(Edit("portal: lateral}", "portal: medial}")).field(),
            "instruments[0].portal");
  EXPECT_EQ(LoadError(Edit("kind: rigid", "kind: liquid")).field(), "bodies[1].kind");
}

TEST_F(ScenarioLoaderTest, YamlSyntaxErrorHasALine) {
  const InputError e = LoadError(Edit("seed: 7", "seed: [7"));
  EXPECT_GT(e.line(), 0);
}

TEST_F(ScenarioLoaderTest, EmptyRegionIsAnError) {
  const InputError e = LoadError(Edit("max: [11, 11, 0.5]", "max: [-0.5, -0.5, -0.5]"));
  EXPECT_EQ(e.field(), "regions[0].box");
}

TEST_F(ScenarioLoaderTest, ContactDefaultsWhenTheSectionIsAbsent) {
  const Model m = LoadScenarioFromText(Valid(), Path());
  const ContactOptions defaults;
  EXPECT_EQ(m.contact.alarm_distance_mm, defaults.alarm_distance_mm);
  EXPECT_EQ(m.contact.contact_distance_mm, 0.1);
  EXPECT_EQ(m.contact.tissue_tissue_stiffness_n_per_mm, defaults.tissue_tissue_stiffness_n_per_mm);
}

TEST_F(ScenarioLoaderTest, ContactSectionIsRead) {
  const Model m = LoadScenarioFromText(
      Edit("seed: 7",
           "seed: 7\ncontact:\n  alarm_distance: 0.8\n  contact_distance: 0.05\n"
           "  max_depth: 2\n  sweep_fraction: 0.25\n  max_substeps: 32\n  thread_bone_reach: 4\n"
           "  stiffness: {tool_tissue: 3, tissue_tissue: 1.5, tool_bone: 7, thread_bone: 30}"),
      Path());
  EXPECT_DOUBLE_EQ(m.contact.alarm_distance_mm, 0.8);
  EXPECT_DOUBLE_EQ(m.contact.contact_distance_mm, 0.05);
  EXPECT_DOUBLE_EQ(m.contact.max_depth_mm, 2.0);
  EXPECT_DOUBLE_EQ(m.contact.sweep_fraction, 0.25);
  EXPECT_EQ(m.contact.max_substeps, 32);
  EXPECT_DOUBLE_EQ(m.contact.tool_tissue_stiffness_n_per_mm, 3.0);
  EXPECT_DOUBLE_EQ(m.contact.tissue_tissue_stiffness_n_per_mm, 1.5);
  EXPECT_DOUBLE_EQ(m.contact.tool_bone_stiffness_n_per_mm, 7.0);
  EXPECT_DOUBLE_EQ(m.contact.thread_bone_stiffness_n_per_mm, 30.0);
  EXPECT_DOUBLE_EQ(m.contact.thread_bone_reach_mm, 4.0);
  EXPECT_DOUBLE_EQ(m.contact.bone_stiffness_n_per_mm, ContactOptions{}.bone_stiffness_n_per_mm);
}

TEST_F(ScenarioLoaderTest, BadContactValuesNameTheField) {
  auto with = [](const std::string& section) { return Edit("seed: 7", "seed: 7\n" + section); };
  const InputError neg = LoadError(with("contact: {alarm_distance: -1}"));
  EXPECT_EQ(neg.field(), "contact.alarm_distance");
  EXPECT_EQ(neg.line(), 3);
  EXPECT_EQ(LoadError(with("contact: {contact_distance: 1.5}")).field(),
            "contact.contact_distance");  // not below the alarm distance
  EXPECT_EQ(LoadError(with("contact: {sweep_fraction: 2}")).field(), "contact.sweep_fraction");
  EXPECT_EQ(LoadError(with("contact: {max_substeps: 0}")).field(), "contact.max_substeps");
  EXPECT_EQ(LoadError(with("contact: {max_depth: far}")).field(), "contact.max_depth");
  EXPECT_EQ(LoadError(with("contact: {alarm: 1}")).field(), "contact.alarm");
  EXPECT_EQ(LoadError(with("contact: {stiffness: {tissue_tissue: 0}}")).field(),
            "contact.stiffness.tissue_tissue");
  EXPECT_EQ(LoadError(with("contact: {stiffness: {tool_tisue: 1}}")).field(),
            "contact.stiffness.tool_tisue");
  EXPECT_EQ(LoadError(with("contact: 3")).field(), "contact");
}

TEST_F(ScenarioLoaderTest, SolverContactToggleAndThreadSolverKeysAreRead) {
  const Model m = LoadScenarioFromText(
      Edit("seed: 7",
           "seed: 7\nsolver: {product: matrix_free, preconditioner: block_jacobi, "
           "refactor_iterations: 0, refactor_slack_iterations: 6}\n"
           "contact: {tissue_tissue_contacts: false, bone_tip_contacts: false}\n"
           "thread_solver: {contact_stiffness: 50, max_strain: 0.02, max_ccd_rounds: 0, "
           "ccd_samples: 4, exclusion_factor: 2, newton_tolerance: 1e-6, max_substep_levels: 3}"),
      Path());
  EXPECT_EQ(m.solver.product, SystemProduct::kMatrixFree);
  EXPECT_EQ(m.solver.preconditioner, Preconditioner::kBlockJacobi);
  EXPECT_EQ(m.solver.refactor_iterations, 0);
  EXPECT_EQ(m.solver.refactor_slack_iterations, 6);
  EXPECT_FALSE(m.contact.tissue_tissue_contacts);
  EXPECT_FALSE(m.contact.bone_tip_contacts);
  EXPECT_TRUE(m.contact.sharp_point_volume_contacts);
  EXPECT_DOUBLE_EQ(m.thread_solver.contact_stiffness_n_per_mm, 50.0);
  EXPECT_DOUBLE_EQ(m.thread_solver.max_strain, 0.02);
  EXPECT_EQ(m.thread_solver.max_ccd_rounds, 0);
  EXPECT_EQ(m.thread_solver.ccd_samples, 4);
  EXPECT_DOUBLE_EQ(m.thread_solver.exclusion_factor, 2.0);
  EXPECT_DOUBLE_EQ(m.thread_solver.newton_tolerance_mm, 1e-6);
  EXPECT_EQ(m.thread_solver.max_substep_levels, 3);
  EXPECT_EQ(m.thread_solver.max_newton_iterations, ThreadSolverOptions{}.max_newton_iterations);
  const Model d = LoadScenarioFromText(Valid(), Path());
  EXPECT_EQ(d.solver.preconditioner, Preconditioner::kRestCholesky);
  EXPECT_EQ(d.solver.refactor_iterations, 10);
  EXPECT_EQ(d.solver.refactor_slack_iterations, 0);
  EXPECT_TRUE(d.contact.tissue_tissue_contacts);
  EXPECT_DOUBLE_EQ(d.thread_solver.max_strain, 0.01);
}

TEST_F(ScenarioLoaderTest, BadOptionValuesNameTheField) {
  auto with = [](const std::string& section) { return Edit("seed: 7", "seed: 7\n" + section); };
  const InputError pre = LoadError(with("solver: {preconditioner: ilu}"));
  EXPECT_EQ(pre.field(), "solver.preconditioner");
  EXPECT_EQ(pre.line(), 3);
  EXPECT_EQ(LoadError(with("solver: {product: sparse}")).field(), "solver.product");
  EXPECT_EQ(LoadError(with("solver: {refactor_iterations: -1}")).field(),
            "solver.refactor_iterations");
  EXPECT_EQ(LoadError(with("solver: {refactor_slack_iterations: -2}")).field(),
            "solver.refactor_slack_iterations");
  EXPECT_EQ(LoadError(with("contact: {bone_tip_contacts: maybe}")).field(),
            "contact.bone_tip_contacts");
  EXPECT_EQ(LoadError(with("thread_solver: {max_strain: 0}")).field(), "thread_solver.max_strain");
  EXPECT_EQ(LoadError(with("thread_solver: {max_substep_levels: 5}")).field(),
            "thread_solver.max_substep_levels");
  EXPECT_EQ(LoadError(with("thread_solver: {ccd_samples: 0}")).field(),
            "thread_solver.ccd_samples");
  EXPECT_EQ(LoadError(with("thread_solver: {compression_stiffness_fraction: 2}")).field(),
            "thread_solver.compression_stiffness_fraction");
  EXPECT_EQ(LoadError(with("thread_solver: {contact_stiffnes: 1}")).field(),
            "thread_solver.contact_stiffnes");
  EXPECT_EQ(LoadError(with("thread_solver: 3")).field(), "thread_solver");
}

}  // namespace
}  // namespace arthrosim::io
