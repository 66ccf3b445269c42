// The tool proxy: instruments stay outside bone whatever the hand does, the fed-back force is the
// handle-proxy coupling, clamped. Each property is also checked with the proxy switched off,
// where it fails (the contrast tests below).
#include "arthrosim/sim/tool_proxy.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>

#include "arthrosim/collision/instrument_shape.h"
#include "arthrosim/collision/tool_bone_query.h"
#include "arthrosim/core/error.h"
#include "arthrosim/core/parallel.h"
#include "arthrosim/input/open_source.h"
#include "arthrosim/io/scenario_loader.h"
#include "arthrosim/sim/step.h"
#include "tool_proxy_scene.h"

namespace arthrosim::sim {
namespace {

// A bone block [-20, 20] x [-20, 20] x [-40, 0] (top face z = 0), a burr and a portal above it.
Model BlockBoneModel() {
  BoneModel bone;
  bone.name = "block";
  bone.surface.nodes.resize(3, 8);
  const double c[8][3] = {{-20, -20, -40}, {20, -20, -40}, {20, 20, -40}, {-20, 20, -40},
                          {-20, -20, 0},   {20, -20, 0},   {20, 20, 0},   {-20, 20, 0}};
  for (int i = 0; i < 8; ++i) bone.surface.nodes.col(i) = Vec3(c[i][0], c[i][1], c[i][2]);
  bone.surface.tris = {{0, 2, 1}, {0, 3, 2}, {4, 5, 6}, {4, 6, 7}, {0, 1, 5}, {0, 5, 4},
                       {2, 3, 7}, {2, 7, 6}, {0, 4, 7}, {0, 7, 3}, {1, 2, 6}, {1, 6, 5}};
  return testing::BurrOverBone("block_bone", std::move(bone));
}

// The burr pointing straight down (tool +z = world -z) with its tip at `tip`.
InputFrame BurrAt(const Vec3& tip) {
  InputFrame f;
  f.tools[0].instrument = 0;
  f.tools[0].pose.position_mm = tip;
  f.tools[0].pose.orientation = Quat(Eigen::AngleAxisd(std::numbers::pi, Vec3::UnitX()));
  return f;
}

using testing::SampledClearance;
using testing::Sim;

// The clearance exactly, by the proxy's own search (closest points of each part's core to every
// bone triangle within 4 mm), from a bone search built afresh for this state: cheap enough for
// every step of a long run.
double ExactClearance(const Model& m, const State& s, int slot) {
  collision::BoneQueryWorld bones;
  collision::SyncBoneQuery(s, &bones);
  return collision::ToolBoneClearance(
             collision::ToolPrimitivesWorld(m, s.tools[static_cast<std::size_t>(slot)]), 4.0,
             &bones)
      .clearance_mm;
}

TEST(ToolProxyTest, HandleSpringGivesTheExpectedForceForAKnownPenetration) {
  Sim r(BlockBoneModel());
  const double k = r.model.haptics.coupling_stiffness_n_per_mm;
  r.Step(BurrAt(Vec3(1, 2, 10)));  // inserted 10 mm above the bone: the proxy is the handle
  EXPECT_EQ(r.state.tools[0].pose, r.state.tools[0].handle_pose);
  EXPECT_EQ(r.state.tools[0].force_n, Vec3::Zero());
  const double depth = 3.0;  // handle tip 3 mm into the bone
  for (int i = 0; i < 3; ++i) r.Step(BurrAt(Vec3(1, 2, -depth)));
  const ToolState& t = r.state.tools[0];
  // The burr sphere (its front is the tip) rests on the top face, straight above the handle.
  EXPECT_NEAR(t.pose.position_mm.z(), 0.0, 0.01);
  EXPECT_NEAR(t.pose.position_mm.x(), 1.0, 1e-9);
  EXPECT_NEAR(t.pose.position_mm.y(), 2.0, 1e-9);
  // The spring stretched by the depth pushes the hand out of the bone (no damping at rest).
  EXPECT_NEAR(t.force_n.z(), k * depth, 0.01 * k);
  EXPECT_NEAR(t.force_n.x(), 0.0, 1e-9);
  EXPECT_NEAR(t.force_n.y(), 0.0, 1e-9);
  EXPECT_GE(SampledClearance(r.model, r.state, 0), -0.1);
  // Bone touch reported for the contact events and the bone operations.
  ASSERT_EQ(r.ws.contacts.bone_touches.size(), 1u);
  EXPECT_NEAR(r.ws.contacts.bone_touches[0].position_mm.z(), 0.0, 1e-9);
}

TEST(ToolProxyTest, WithoutTheProxyTheHandleEntersTheBone) {
  Model m = BlockBoneModel();
  m.haptics.proxy = false;
  Sim r(std::move(m));
  r.Step(BurrAt(Vec3(1, 2, 10)));
  for (int i = 0; i < 3; ++i) r.Step(BurrAt(Vec3(1, 2, -3)));
  EXPECT_LT(SampledClearance(r.model, r.state, 0), -0.1);
}

// A hand pressing the burr into bone with a 20 N target (admittance: depth rate = gain * (target
// - fed-back force), as a script's force push): the burr stays on the surface, nothing is
// removed, and the fed-back coupling force settles at the push.
double PressBurr(Sim* r, double target_n) {
  r->Step(BurrAt(Vec3(0, 0, 5)));
  double z = 5.0;
  for (int i = 0; i < 300; ++i) {
    const double pressing = r->state.tools[0].force_n.z();
    z -= std::clamp(5.0 * (target_n - pressing), -10.0, 10.0) * r->model.options.dt_s;
    r->Step(BurrAt(Vec3(0, 0, z)));
  }
  return r->state.tools[0].force_n.z();
}

TEST(ToolProxyTest, BurrPressedIntoBoneWith20NStaysOnTheSurface) {
  Sim run(BlockBoneModel());
  Sim* r = &run;
  const double force = PressBurr(r, 20.0);
  EXPECT_NEAR(force, 20.0, 0.05);
  const ToolState& t = r->state.tools[0];
  const double k = r->model.haptics.coupling_stiffness_n_per_mm;
  EXPECT_NEAR((t.pose.position_mm - t.handle_pose.position_mm).norm() * k, 20.0, 0.05);
  const double clearance = SampledClearance(r->model, r->state, 0);
  EXPECT_GE(clearance, -0.1);
  EXPECT_LE(clearance, 0.1);  // on the surface, not hovering
  EXPECT_EQ(r->state.bones[0].revision, 0u);
  EXPECT_EQ(r->state.bones[0].surface.nodes, r->model.bones[0].surface.nodes);
}

TEST(ToolProxyTest, WithoutTheProxyThePressedBurrSinksIntoTheBone) {
  Model m = BlockBoneModel();
  m.haptics.proxy = false;
  Sim r(std::move(m));
  PressBurr(&r, 20.0);
  EXPECT_LT(SampledClearance(r.model, r.state, 0), -0.1);
}

TEST(ToolProxyTest, ForceIsClampedToTheDeviceMaximum) {
  Model m = BlockBoneModel();
  m.haptics.max_force_n = 3.3;  // a Touch
  Sim r(std::move(m));
  r.Step(BurrAt(Vec3(0, 0, 10)));
  for (int i = 0; i < 3; ++i) r.Step(BurrAt(Vec3(0, 0, -30)));
  EXPECT_NEAR(r.state.tools[0].force_n.norm(), 3.3, 1e-12);
  EXPECT_GE(SampledClearance(r.model, r.state, 0), -0.1);
}

TEST(ToolProxyTest, ProxySlidesAlongTheSurfaceTowardTheHandle) {
  Sim r(BlockBoneModel());
  r.Step(BurrAt(Vec3(-10, 0, 5)));
  r.Step(BurrAt(Vec3(-10, 0, -2)));                                              // pressed 2 mm in
  for (int i = 0; i < 5; ++i) r.Step(BurrAt(Vec3(-10 + 4.0 * (i + 1), 0, -2)));  // slid along x
  const ToolState& t = r.state.tools[0];
  EXPECT_NEAR(t.pose.position_mm.x(), 10.0, 1e-3);  // the slide converges toward it
  EXPECT_NEAR(t.pose.position_mm.z(), 0.0, 0.01);
  EXPECT_GE(SampledClearance(r.model, r.state, 0), -0.1);
}

// An axis-aligned box [lo, hi] as one more bone of `m` (outward-facing triangles).
void AddBoxBone(Model* m, const std::string& name, const Vec3& lo, const Vec3& hi) {
  BoneModel bone;
  bone.name = name;
  bone.surface.nodes.resize(3, 8);
  for (int i = 0; i < 8; ++i) {
    bone.surface.nodes.col(i) =
        Vec3((i & 1) == 0 ? lo.x() : hi.x(), ((i >> 1) & 1) == 0 ? lo.y() : hi.y(),
             ((i >> 2) & 1) == 0 ? lo.z() : hi.z());
  }
  // corners i = x + 2y + 4z; each face wound counter-clockwise seen from outside
  bone.surface.tris = {{0, 2, 3}, {0, 3, 1}, {4, 5, 7}, {4, 7, 6}, {0, 1, 5}, {0, 5, 4},
                       {2, 6, 7}, {2, 7, 3}, {0, 4, 6}, {0, 6, 2}, {1, 3, 7}, {1, 7, 5}};
  m->bones.push_back(bone);
}

// The burr resting on the top face z = 0 at (x, y), the hand 3 mm in; then one step with the
// hand at `handle`: the proxy's position after that step, its resolution iterations in
// *iterations.
Vec3 RestThenMoveHand(Sim* r, double x, double y, const Vec3& handle, int* iterations) {
  r->Step(BurrAt(Vec3(x, y, 5)));
  for (int i = 0; i < 3; ++i) r->Step(BurrAt(Vec3(x, y, -3)));
  EXPECT_NEAR(r->state.tools[0].pose.position_mm.x(), x, 1e-9);
  EXPECT_NEAR(r->state.tools[0].pose.position_mm.z(), 0.0, 0.01);
  r->Step(BurrAt(handle));
  *iterations = r->ws.proxy.iterations[0];
  return r->state.tools[0].pose.position_mm;
}

// The god-object's slide: the burr rests on a flat face with the hand 3 mm in; the hand moves
// 2 mm along the face within one step. The proxy slides to the face straight above the handle in
// that step, in a few resolution iterations (one per 0.25 mm of slide and one to arrive). A proxy
// that advances 0.25 mm toward the handle and is pushed out again creeps along the face by a
// shrinking fraction of the remaining way (~0.92 per iteration: it stops at the 96-iteration cap,
// short of the handle).
// A bone block with the sliding proxy on (haptics.slide).
Model SlidingBlockBoneModel() {
  Model m = BlockBoneModel();
  m.haptics.slide = true;
  return m;
}

TEST(ToolProxyTest, HandMovedAlongAFaceItPressesIntoSlidesTheProxyInAFewIterations) {
  Sim r(SlidingBlockBoneModel());
  int iterations = 0;
  const Vec3 p = RestThenMoveHand(&r, 0, 1, Vec3(2, 1, -3), &iterations);
  std::printf("slide along a face: proxy (%.6f, %.6f, %.6f) in %d iterations\n", p.x(), p.y(),
              p.z(), iterations);
  EXPECT_NEAR(p.x(), 2.0, 1e-6);
  EXPECT_NEAR(p.y(), 1.0, 1e-6);
  EXPECT_NEAR(p.z(), 0.0, 0.01);  // the burr sphere's front on the face
  EXPECT_LE(iterations, 10);
  EXPECT_GE(SampledClearance(r.model, r.state, 0), -0.1);
}

// The contrast: the earlier proxy (haptics.slide false) creeps along the face, runs into the
// iteration cap and ends short of the handle's projection.
TEST(ToolProxyTest, WithoutTheSlideTheProxyCreepsAlongTheFace) {
  Model m = BlockBoneModel();
  m.haptics.slide = false;  // the earlier proxy (the default slides)
  Sim r(std::move(m));
  int iterations = 0;
  const Vec3 p = RestThenMoveHand(&r, 0, 1, Vec3(2, 1, -3), &iterations);
  EXPECT_EQ(iterations, kProxyMaxIterations);
  EXPECT_LT(p.x(), 2.0 - 1e-4);
}

// A concave corner: the burr resting on a floor is moved by the hand past a wall into the crease
// (the hand 4 mm behind the wall and 3 mm under the floor): it slides into the crease and stops
// there touching both faces, in about one iteration per 0.25 mm of the way (the zig-zagging proxy
// creeps into the crease and needs several times as many).
TEST(ToolProxyTest, PushIntoACreaseOfTwoFacesStopsInTheCrease) {
  Model m = SlidingBlockBoneModel();                            // floor: top face z = 0
  AddBoxBone(&m, "wall", Vec3(0, -20, -10), Vec3(20, 20, 20));  // wall: face x = 0
  Sim r(std::move(m));
  const double radius = r.model.instruments[0].tip_radius_mm;  // = the shaft's
  int iterations = 0;
  const Vec3 p = RestThenMoveHand(&r, -5, 1, Vec3(4, 1, -3), &iterations);
  std::printf("crease: proxy (%.6f, %.6f, %.6f) in %d iterations\n", p.x(), p.y(), p.z(),
              iterations);
  EXPECT_NEAR(p.x(), -radius, 0.01);
  EXPECT_NEAR(p.y(), 1.0, 1e-6);
  EXPECT_NEAR(p.z(), 0.0, 0.01);
  EXPECT_LE(iterations, 2 + static_cast<int>((5 - radius) / 0.25));
  EXPECT_GE(SampledClearance(r.model, r.state, 0), -0.1);
  // Coming from above the floor in one step, the burr also ends in the crease (it closes its
  // clearance to the wall it met before the floor, not only to the nearest surface).
  Sim above(r.model);
  above.Step(BurrAt(Vec3(-10, 1, 5)));
  above.Step(BurrAt(Vec3(4, 1, -3)));
  const Vec3 q = above.state.tools[0].pose.position_mm;
  EXPECT_NEAR(q.x(), -radius, 0.01);
  EXPECT_NEAR(q.z(), 0.0, 0.01);
}

// The same into a corner of three faces (floor, wall x = 0, wall y = 0): the burr stops in the
// corner touching all three.
TEST(ToolProxyTest, PushIntoACornerOfThreeFacesStopsInTheCorner) {
  Model m = SlidingBlockBoneModel();                              // floor: top face z = 0
  AddBoxBone(&m, "wall_x", Vec3(0, -20, -10), Vec3(20, 20, 20));  // face x = 0
  AddBoxBone(&m, "wall_y", Vec3(-20, 0, -10), Vec3(20, 20, 20));  // face y = 0
  Sim r(std::move(m));
  const double radius = r.model.instruments[0].tip_radius_mm;
  int iterations = 0;
  const Vec3 p = RestThenMoveHand(&r, -5, -5, Vec3(4, 3, -3), &iterations);
  std::printf("corner: proxy (%.6f, %.6f, %.6f) in %d iterations\n", p.x(), p.y(), p.z(),
              iterations);
  EXPECT_NEAR(p.x(), -radius, 0.01);
  EXPECT_NEAR(p.y(), -radius, 0.01);
  EXPECT_NEAR(p.z(), 0.0, 0.01);
  EXPECT_LE(iterations, 2 + static_cast<int>(std::sqrt(2.0) * (5 - radius) / 0.25));
  EXPECT_GE(SampledClearance(r.model, r.state, 0), -0.1);
  Sim above(r.model);  // from above the floor in one step
  above.Step(BurrAt(Vec3(-10, -8, 5)));
  above.Step(BurrAt(Vec3(4, 3, -3)));
  const Vec3 q = above.state.tools[0].pose.position_mm;
  EXPECT_NEAR(q.x(), -radius, 0.01);
  EXPECT_NEAR(q.y(), -radius, 0.01);
  EXPECT_NEAR(q.z(), 0.0, 0.01);
}

TEST(ToolProxyTest, HandleTeleportedThroughTheBoneDoesNotTunnel) {
  Sim r(BlockBoneModel());
  r.Step(BurrAt(Vec3(0, 0, 5)));
  r.Step(BurrAt(Vec3(0, 0, -60)));  // below the block: the straight path crosses 40 mm of bone
  EXPECT_GT(r.state.tools[0].pose.position_mm.z(), 0.0);
  EXPECT_GE(SampledClearance(r.model, r.state, 0), -0.1);
}

TEST(ToolProxyTest, InstrumentInsertedInsideBoneStartsAtItsPortal) {
  Sim r(BlockBoneModel());
  r.Step(BurrAt(Vec3(0, 0, -10)));
  EXPECT_GE(SampledClearance(r.model, r.state, 0), -0.1);
  EXPECT_GT(r.state.tools[0].pose.position_mm.z(), 0.0);
}

TEST(ToolProxyTest, ScenarioKeysAreReadAndChecked) {
  const std::string base = "name: h\nmaterials: {}\nbodies: []\n";
  const Model m =
      io::LoadScenarioFromText(base +
                                   "haptics: {proxy: false, slide: true, "
                                   "coupling_stiffness_n_per_mm: 0.5, "
                                   "coupling_damping_n_s_per_mm: 0.001, max_force_n: 3.3}\n",
                               "h.yaml");
  EXPECT_FALSE(m.haptics.proxy);
  EXPECT_TRUE(m.haptics.slide);
  EXPECT_EQ(m.haptics.coupling_stiffness_n_per_mm, 0.5);
  EXPECT_EQ(m.haptics.coupling_damping_n_s_per_mm, 0.001);
  EXPECT_EQ(m.haptics.max_force_n, 3.3);
  // A scenario that says nothing gets the sliding god-object proxy; `slide: false` the earlier one.
  EXPECT_TRUE(io::LoadScenarioFromText(base, "h.yaml").haptics.slide);
  EXPECT_FALSE(
      io::LoadScenarioFromText(base + "haptics: {slide: false}\n", "h.yaml").haptics.slide);
  try {
    io::LoadScenarioFromText(base + "haptics: {max_force_n: -1}\n", "h.yaml");
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("haptics.max_force_n"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("h.yaml:4"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace arthrosim::sim

namespace arthrosim::sim {
namespace {

Model Shoulder(bool proxy = true) {
  Model m =
      io::LoadScenario(std::string(ARTHROSIM_SOURCE_DIR) + "/scenarios/rotator_cuff_repair.yaml");
  m.haptics.proxy = proxy;
  return m;
}

// Largest displacement of any node of `body` from its rest position, mm, and the smallest
// signed distance of those nodes from the bones (mm, < 0 inside).
struct TissueFigures {
  double max_displacement_mm = 0;
  double min_bone_distance_mm = 1e300;
};
TissueFigures Tissue(const Model& m, const State& s, int body) {
  TissueFigures f;
  collision::BoneQueryWorld bones;
  collision::SyncBoneQuery(s, &bones);
  const Points& x = s.soft_bodies[static_cast<std::size_t>(body)].x;
  const Points& x0 = m.soft_bodies[static_cast<std::size_t>(body)].rest_mesh.nodes;
  for (Eigen::Index i = 0; i < x0.cols(); ++i) {
    f.max_displacement_mm = std::max(f.max_displacement_mm, (x.col(i) - x0.col(i)).norm());
    f.min_bone_distance_mm =
        std::min(f.min_bone_distance_mm, collision::PointBoneSignedDistance(x.col(i), &bones));
  }
  return f;
}

}  // namespace
}  // namespace arthrosim::sim

namespace arthrosim::sim {
namespace {

// The abusive replay of trajectories/abusive_sweep.yaml (a grasper swept at 0.5 m/s through the
// head and the cuff), `steps` steps or to its end (steps < 0).
struct SweepResult {
  State state;
  int steps = 0;
  double min_tool_clearance_mm = 1e300;
  double max_force_n = 0;
  int max_cg_iterations = 0;
  int refactors = 0;
  double max_tissue_displacement_mm = 0;
  int proxy_apart_steps = 0;  ///< steps ending with the proxy away from its handle
};
SweepResult Sweep(const Model& m, int steps, bool measure = true) {
  input::SourceOptions options;
  options.dt_s = m.options.dt_s;
  auto source = input::OpenInputSource(
      std::string(ARTHROSIM_SOURCE_DIR) + "/trajectories/abusive_sweep.yaml", m, options);
  Sim r(m);
  SweepResult out;
  InputFrame f;
  for (int k = 0; steps < 0 || k < steps; ++k) {
    const double t = static_cast<double>(r.state.step + 1) * m.options.dt_s;
    if (source->Finished(t)) break;
    source->Frame(r.state.step + 1, t, &f);
    r.Step(f);
    source->Feedback(Feedback(r.state));
    ++out.steps;
    out.proxy_apart_steps += r.state.tools[0].pose == r.state.tools[0].handle_pose ? 0 : 1;
    if (!measure) continue;
    out.min_tool_clearance_mm =
        std::min(out.min_tool_clearance_mm, ExactClearance(r.model, r.state, 0));
    out.max_force_n = std::max(out.max_force_n, r.state.tools[0].force_n.norm());
    out.max_cg_iterations = std::max(out.max_cg_iterations, r.ws.timings.soft.cg_iterations);
    out.refactors += r.ws.timings.soft.refactored ? 1 : 0;
  }
  if (measure) {
    for (int b = 0; b < static_cast<int>(m.soft_bodies.size()); ++b) {
      out.max_tissue_displacement_mm =
          std::max(out.max_tissue_displacement_mm, Tissue(m, r.state, b).max_displacement_mm);
    }
  }
  out.state = r.state;
  return out;
}

TEST(ToolProxyTest, AbusiveSweepKeepsTheToolOutOfBoneAndTheForceClamped) {
  const Model m = Shoulder();
  const SweepResult s = Sweep(m, 100);
  std::printf(
      "abusive sweep: %d steps, tool clearance %.3f mm, max force %.3f N, max tissue "
      "displacement %.3f mm, CG max %d it, %d refactors\n",
      s.steps, s.min_tool_clearance_mm, s.max_force_n, s.max_tissue_displacement_mm,
      s.max_cg_iterations, s.refactors);
  EXPECT_EQ(s.steps, 100);
  EXPECT_GE(s.min_tool_clearance_mm, -0.1);
  EXPECT_LE(s.max_force_n, m.haptics.max_force_n + 1e-9);
}

TEST(ToolProxyTest, AbusiveSweepWithoutTheProxyEntersBone) {
  const SweepResult s = Sweep(Shoulder(false), 100);
  std::printf("abusive sweep, no proxy: tool clearance %.3f mm, max tissue displacement %.3f mm\n",
              s.min_tool_clearance_mm, s.max_tissue_displacement_mm);
  EXPECT_LT(s.min_tool_clearance_mm, -0.1);
}

TEST(ToolProxyTest, AbusiveSweepIsBitIdenticalForOneAndTwoThreads) {
  const Model m = Shoulder();
  SetThreadCount(1);
  const SweepResult a = Sweep(m, 100, false);
  SetThreadCount(2);
  const SweepResult b = Sweep(m, 100, false);
  SetThreadCount(1);
  EXPECT_TRUE(BitwiseEqual(a.state, b.state));
  EXPECT_EQ(HashState(a.state), HashState(b.state));
  EXPECT_GT(a.proxy_apart_steps, 0);  // the proxy did act
}

}  // namespace
}  // namespace arthrosim::sim

namespace arthrosim::sim {
namespace {

// The awl operation (trajectories/ops/awl.yaml: the pilot hole driven into the humeral head), run
// with the proxy's two shortcuts (a step whose inputs equal the step before's takes its result;
// a resolution whose iteration state repeats an earlier one bit for bit ends where the cycle
// would be after the 96 iterations) and without: the same State, bit for bit, after every step.
// Both shortcuts act here (the awl wedged in its hole alternates between its walls: 5 cycles, 5
// steps taken from the step before). Fails with the cycle's end taken one iteration early
// (first + (96 - first) % period - 1: the tool pose differs at step 178) and with the start pose
// left out of the step's inputs (step 152). Release only (two shoulder runs of 500 steps, ~6 s;
// minutes under the sanitizers, where the expert and operation runs take the same paths).
TEST(ToolProxyTest, ShortcutsOfTheAwlInItsHoleGiveTheFullResolutionBitForBit) {
#if defined(__SANITIZE_ADDRESS__)
  GTEST_SKIP() << "Release only (two shoulder runs)";
#endif
  const Model m = Shoulder();
  input::SourceOptions options;
  options.dt_s = m.options.dt_s;
  const std::string script = std::string(ARTHROSIM_SOURCE_DIR) + "/trajectories/ops/awl.yaml";
  auto with = input::OpenInputSource(script, m, options);
  auto without = input::OpenInputSource(script, m, options);
  Sim a(m), b(m);
  b.ws.proxy.shortcuts = false;
  int cycles = 0, reused = 0, steps = 0;
  InputFrame fa, fb;
  for (;; ++steps) {
    const double t = static_cast<double>(a.state.step + 1) * m.options.dt_s;
    if (with->Finished(t)) break;
    with->Frame(a.state.step + 1, t, &fa);
    without->Frame(b.state.step + 1, t, &fb);
    a.Step(fa);
    b.Step(fb);
    with->Feedback(Feedback(a.state));
    without->Feedback(Feedback(b.state));
    cycles += a.ws.proxy.cycles;
    reused += a.ws.proxy.reused;
    ASSERT_EQ(b.ws.proxy.cycles + b.ws.proxy.reused, 0);
    ASSERT_TRUE(a.state.tools[0].pose == b.state.tools[0].pose &&
                a.state.tools[1].pose == b.state.tools[1].pose)
        << "step " << a.state.step;
    ASSERT_TRUE(BitwiseEqual(a.state, b.state)) << "step " << a.state.step;
  }
  std::printf(
      "awl operation: %d steps, %d resolutions ended by a repeated state, %d taken from "
      "the step before\n",
      steps, cycles, reused);
  EXPECT_EQ(steps, 500);
  EXPECT_GT(cycles, 0);
  EXPECT_GT(reused, 0);
}

}  // namespace
}  // namespace arthrosim::sim
