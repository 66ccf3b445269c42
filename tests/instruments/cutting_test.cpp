#include "arthrosim/instruments/cutting.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "../collision/clip_reference.h"
#include "arthrosim/core/parallel.h"
#include "arthrosim/physics/constraints.h"
#include "arthrosim/sim/step.h"
#include "arthrosim/sim/workspace.h"
#include "op_scene.h"

namespace arthrosim::instruments {
namespace {

using testing::AliveComponents;
using testing::AliveRestVolume;
using testing::DetailInt;
using testing::DetailNumber;
using testing::EventsOf;
using testing::GridMesh;
using testing::GridModel;
using testing::kMinSplitQuality;
using testing::SceneRun;
using testing::ToolInput;

// Independent reference for "the triangle crosses the tet".
bool Crosses(const std::array<Vec3, 3>& tri, const std::array<Vec3, 4>& p) {
  return collision::testing::ClipReference(tri[0], tri[1], tri[2], p);
}

std::array<Vec3, 4> TetAt(const SoftBodyState& b, std::size_t t) {
  const mesh::Tet& e = b.tets[t];
  return {b.x.col(e[0]), b.x.col(e[1]), b.x.col(e[2]), b.x.col(e[3])};
}

// A bar along x (20 x 3 x 3 mm, 1 mm cells) centred on the x axis, fixed at both ends: a biceps
// stand-in. The scissors come from above (forward = -z) with the blades opening along y, their
// plane x = 10.5 across the bar, tip 2 mm below the bar's axis: the bar's cross-section lies in
// the wedge between the open blades, touching them near the hinge.
struct BarScene {
  Model model = GridModel(GridMesh(Vec3(0, -1.5, -1.5), {20, 3, 3}, 1.0),
                          [](const Vec3& p) { return p.x() < 0.01 || p.x() > 19.99; });
  InputFrame Scissors(double jaw) const {
    return ToolInput(model, "scissors", Vec3(10.5, 0, -2.0), Vec3(0, 1, 0), Vec3(0, 0, -1), jaw, 0);
  }
};

TEST(ScissorsCut, RemovesOnlyTetsTheBladeTriangleCrossesAndCutsTheBarInTwo) {
  BarScene scene;
  const Model& m = scene.model;
  SceneRun run(m);
  auto& [s, ws] = run;
  sim::Step(m, scene.Scissors(0.0), &s, &ws);  // open, in place: no cut
  EXPECT_TRUE(EventsOf(s, "cut").empty());
  ASSERT_EQ(AliveComponents(s, 0), 1);
  const double v0 = AliveRestVolume(s, 0);
  const std::vector<std::uint8_t> alive_before = s.soft_bodies[0].tet_alive;
  sim::Step(m, scene.Scissors(0.1), &s, &ws);  // the jaw starts to close
  const std::vector<Event> cuts = EventsOf(s, "cut");
  ASSERT_EQ(cuts.size(), 1u);
  std::array<Vec3, 3> tri;
  ASSERT_TRUE(BladeTriangle(m, s.tools[0], &tri));
  const SoftBodyState& b = s.soft_bodies[0];
  int removed = 0;
  for (std::size_t t = 0; t < b.tets.size(); ++t) {
    if (!alive_before[t]) continue;
    const bool crosses = Crosses(tri, TetAt(b, t));
    // Removed exactly when the blade triangle crosses it (at the positions of the cut).
    EXPECT_EQ(b.tet_alive[t] == 0, crosses) << "tet " << t;
    removed += b.tet_alive[t] == 0 ? 1 : 0;
  }
  EXPECT_GT(removed, 0);
  EXPECT_EQ(DetailInt(cuts[0].detail, "tets"), removed);
  const double volume = DetailNumber(cuts[0].detail, "volume_mm3");
  EXPECT_NEAR(volume, v0 - AliveRestVolume(s, 0), 1e-9 * v0);
  EXPECT_NEAR(b.removed_volume_mm3, volume, 1e-12);
  // The cut is thin (one layer around the plane x = 10.5) and goes through the whole bar.
  EXPECT_LT(volume, 2.0 * 9.0);
  EXPECT_EQ(AliveComponents(s, 0), 2);
  // The collision surface follows at the next step: the boundary of the alive tets, now with
  // the cut faces.
  const std::size_t tris_before = ws.collision.soft[0].surface.tris.size();
  sim::Step(m, scene.Scissors(0.1), &s, &ws);
  EXPECT_EQ(ws.collision.soft[0].surface.tris,
            collision::BoundaryTriangles(s.soft_bodies[0].tets, s.soft_bodies[0].tet_alive));
  EXPECT_GT(ws.collision.soft[0].surface.tris.size(), tris_before);
}

TEST(ScissorsCut, NothingHappensWithoutClosingOrWithoutTouching) {
  BarScene scene;
  const Model& m = scene.model;
  SceneRun run(m);
  auto& [s, ws] = run;
  // The jaw held at 0.5 (not closing) in place: contacts but no cut.
  for (int k = 0; k < 5; ++k) sim::Step(m, scene.Scissors(0.5), &s, &ws);
  EXPECT_EQ(AliveRestVolume(s, 0), AliveRestVolume(MakeInitialState(m), 0));
  // Closing far from the bar: no contact, no cut.
  InputFrame away =
      ToolInput(m, "scissors", Vec3(10.5, 0, 30), Vec3(0, 1, 0), Vec3(0, 0, -1), 0.0, 0);
  SceneRun run_s2(m);
  auto& [s2, ws2] = run_s2;
  sim::Step(m, away, &s2, &ws2);
  away.tools[0].jaw = 0.5;
  sim::Step(m, away, &s2, &ws2);
  EXPECT_TRUE(EventsOf(s2, "cut").empty());
  for (std::uint8_t a : s2.soft_bodies[0].tet_alive) ASSERT_EQ(a, 1);
}

// A sheet in z = [-0.5, 0.5] (60 x 8 x 1 mm) held along its long sides; the scissors advance
// along +x (0.4 mm per step) with the blades opening along z (blade plane y = 0.2), closing a
// little every step: paper-cutting, 150 steps of continuous cutting. Not every step reaches a
// new 1 mm element, but the cut keeps up with the blade tips at every step.
TEST(ScissorsCut, ProgressiveCuttingOverOneHundredFiftySteps) {
  const Model m = GridModel(GridMesh(Vec3(0, -4, -0.5), {66, 8, 1}, 1.0),
                            [](const Vec3& p) { return std::abs(std::abs(p.y()) - 4) < 0.01; });
  SceneRun run(m);
  auto& [s, ws] = run;
  const int steps = 150;
  int cut_steps = 0;
  double front = -1;  // largest x reached by a removed tet's centroid
  for (int k = 0; k <= steps; ++k) {
    const double tip_x = 3.0 + 0.4 * k;
    const InputFrame in = ToolInput(m, "scissors", Vec3(tip_x, 0.2, 0), Vec3(0, 0, 1),
                                    Vec3(1, 0, 0), 0.9 * k / steps, 0);
    sim::Step(m, in, &s, &ws);
    ASSERT_TRUE(s.soft_bodies[0].x.allFinite()) << "step " << k;
    for (const Event& e : EventsOf(s, "cut")) {
      ++cut_steps;
      EXPECT_GE(DetailInt(e.detail, "tets"), 1);
      front = std::max(front, e.position_mm.x());
    }
    // The cut keeps up with the blade tips (within two cells behind them).
    if (k > 1) {
      EXPECT_GT(front, tip_x - 2.0) << "step " << k;
    }
  }
  EXPECT_GE(cut_steps, 80);
  EXPECT_GT(front, 60.0);
  // Every remaining element positive at rest.
  const SoftBodyState& b = s.soft_bodies[0];
  for (std::size_t t = 0; t < b.tets.size(); ++t) {
    if (!b.tet_alive[t]) continue;
    const mesh::Tet& e = b.tets[t];
    const Vec3 a = b.x_rest.col(e[0]);
    EXPECT_GT((b.x_rest.col(e[1]) - a).dot((b.x_rest.col(e[2]) - a).cross(b.x_rest.col(e[3]) - a)),
              0);
  }
}

State RunProgressive(int threads, CutMode mode = CutMode::kRemove) {
  SetThreadCount(threads);
  Model m = GridModel(GridMesh(Vec3(0, -4, -0.5), {30, 8, 1}, 1.0),
                      [](const Vec3& p) { return std::abs(std::abs(p.y()) - 4) < 0.01; });
  m.operations.scissors.mode = mode;
  SceneRun run(m);
  auto& [s, ws] = run;
  for (int k = 0; k <= 40; ++k) {
    sim::Step(m,
              ToolInput(m, "scissors", Vec3(3.0 + 0.4 * k, 0.2, 0), Vec3(0, 0, 1), Vec3(1, 0, 0),
                        0.02 * k, 0),
              &s, &ws);
  }
  SetThreadCount(1);
  return s;
}

TEST(ScissorsCut, BitIdenticalWithOneAndTwoThreads) {
  const State a = RunProgressive(1), b = RunProgressive(2), c = RunProgressive(1);
  EXPECT_TRUE(BitwiseEqual(a, c));
  EXPECT_TRUE(BitwiseEqual(a, b));
  EXPECT_GT(a.soft_bodies[0].removed_volume_mm3, 0);
}

TEST(ScissorsSplit, BitIdenticalWithOneAndTwoThreads) {
  const State a = RunProgressive(1, CutMode::kSplit), b = RunProgressive(2, CutMode::kSplit),
              c = RunProgressive(1, CutMode::kSplit);
  EXPECT_TRUE(BitwiseEqual(a, c));
  EXPECT_TRUE(BitwiseEqual(a, b));
  EXPECT_GT(a.soft_bodies[0].tets.size(), 30u * 8u * 6u);  // the grid's tets, then pieces
}

// ---- Split mode -------------------------------------------------------------------------

void ExpectValidMesh(const SoftBodyState& b) {
  for (std::size_t t = 0; t < b.tets.size(); ++t) {
    if (!b.tet_alive[t]) continue;
    const mesh::Tet& e = b.tets[t];
    for (const Points* x : {&b.x_rest, &b.x}) {
      const Vec3 a = x->col(e[0]);
      ASSERT_GT((x->col(e[1]) - a).dot((x->col(e[2]) - a).cross(x->col(e[3]) - a)), 0)
          << "tet " << t;
    }
  }
}

TEST(ScissorsSplit, CutsTheBarInTwoConservingVolumeWithValidElements) {
  BarScene scene;
  scene.model.operations.scissors.mode = CutMode::kSplit;
  const Model& m = scene.model;
  SceneRun run(m);
  auto& [s, ws] = run;
  sim::Step(m, scene.Scissors(0.0), &s, &ws);
  const double v0 = AliveRestVolume(s, 0);
  const std::size_t tets0 = s.soft_bodies[0].tets.size();
  sim::Step(m, scene.Scissors(0.1), &s, &ws);
  const std::vector<Event> cuts = EventsOf(s, "cut");
  ASSERT_EQ(cuts.size(), 1u);
  EXPECT_NE(cuts[0].detail.find("mode=split"), std::string::npos);
  const SoftBodyState& b = s.soft_bodies[0];
  EXPECT_GT(b.tets.size(), tets0);
  EXPECT_NEAR(AliveRestVolume(s, 0), v0, 1e-9 * v0);
  EXPECT_EQ(b.removed_volume_mm3, 0);
  ExpectValidMesh(b);
  for (std::size_t t = tets0; t < b.tets.size(); ++t) {
    const mesh::Tet& e = b.tets[t];
    EXPECT_GE(
        RadiusRatio(b.x_rest.col(e[0]), b.x_rest.col(e[1]), b.x_rest.col(e[2]), b.x_rest.col(e[3])),
        kMinSplitQuality)
        << "tet " << t;
  }
  EXPECT_EQ(AliveComponents(s, 0), 2);
  // The pieces hang apart afterwards, still valid.
  InputFrame idle;
  idle.camera.pose = m.camera.initial_pose;
  for (int k = 0; k < 30; ++k) sim::Step(m, idle, &s, &ws);
  ASSERT_TRUE(s.soft_bodies[0].x.allFinite());
  EXPECT_NEAR(AliveRestVolume(s, 0), v0, 1e-9 * v0);
}

// The progressive split cut of a sheet over 150 steps, on four paths: split_progressive_test.cpp.

// Each alive tet of body 0 on one side of the plane: no tet has nodes farther than `tol_mm`
// from it on both sides.
bool EveryTetOnOneSide(const State& s, const Vec3& point, const Vec3& normal, double tol_mm) {
  const SoftBodyState& b = s.soft_bodies[0];
  for (std::size_t t = 0; t < b.tets.size(); ++t) {
    if (!b.tet_alive[t]) continue;
    bool above = false, below = false;
    for (std::int32_t n : b.tets[t]) {
      const double d = normal.dot(Vec3(b.x.col(n)) - point);
      above |= d > tol_mm;
      below |= d < -tol_mm;
    }
    if (above && below) return false;
  }
  return true;
}

TEST(ScissorsSplit, RandomPlanesGiveValidSeparatedPiecesOfBoundedQuality) {
  // 300 planes in every direction through a 4 x 4 x 4 grid (unit cubes of six tets, radius
  // ratio 0.72), each cut with a triangle covering the grid: the rest volume is conserved to
  // 1e-9, every element is positive with radius ratio >= kMinSplitQuality, every tet lies on
  // one side of the plane (nodes snapped to it may lie up to snap_fraction of an edge, 0.2 x
  // sqrt(3) mm, off it), and the grid falls apart into exactly two pieces. (With the sequential
  // edge bisection this replaced: worst radius ratio 0.0009, tets across the plane, and two of
  // the 300 planes left the sides joined at a snapped node.)
  Model m = GridModel(GridMesh(Vec3(0, 0, 0), {4, 4, 4}, 1.0), [](const Vec3&) { return false; });
  std::uint64_t seed = 12345;
  auto uniform = [&seed] {
    seed = seed * 6364136223846793005ull + 1442695040888963407ull;
    return static_cast<double>(seed >> 11) / 9007199254740992.0;
  };
  const double snap = m.operations.scissors.snap_fraction;
  double worst = 1;
  int apart = 0;
  for (int trial = 0; trial < 300; ++trial) {
    SceneRun run(m);
    auto& [s, ws] = run;
    const Vec3 normal = Vec3(uniform() - 0.5, uniform() - 0.5, uniform() - 0.5).normalized();
    const Vec3 point(0.5 + 3 * uniform(), 0.5 + 3 * uniform(), 0.5 + 3 * uniform());
    // A triangle in that plane big enough to cover the grid.
    const Vec3 u = normal.unitOrthogonal(), w = normal.cross(u);
    const std::array<Vec3, 3> tri{point + 20 * u, point - 10 * u + 17 * w, point - 10 * u - 17 * w};
    collision::TetTree tree;
    std::vector<std::int32_t> crossed;
    TetsCrossedByTriangle(s, 0, tri, &tree, &crossed);
    const double v0 = AliveRestVolume(s, 0);
    const std::size_t tets0 = s.soft_bodies[0].tets.size();
    SplitTetsByPlane(m, 0, crossed, point, normal, snap, &tree, &ws.soft, &s);
    const SoftBodyState& b = s.soft_bodies[0];
    ASSERT_NEAR(AliveRestVolume(s, 0), v0, 1e-9 * v0) << "trial " << trial;
    ExpectValidMesh(b);
    for (std::size_t t = tets0; t < b.tets.size(); ++t) {
      const mesh::Tet& e = b.tets[t];
      const double q = RadiusRatio(b.x_rest.col(e[0]), b.x_rest.col(e[1]), b.x_rest.col(e[2]),
                                   b.x_rest.col(e[3]));
      worst = std::min(worst, q);
      EXPECT_GE(q, kMinSplitQuality) << "trial " << trial << ", tet " << t;
    }
    EXPECT_TRUE(EveryTetOnOneSide(s, point, normal, snap * std::sqrt(3.0) + 1e-9))
        << "trial " << trial;
    apart += AliveComponents(s, 0) == 2;
    EXPECT_EQ(AliveComponents(s, 0), 2) << "trial " << trial;
  }
  std::printf("worst split quality %.4f, %d of 300 cut apart\n", worst, apart);
}

// ---- Cutter ----------------------------------------------------------------------------

// The small scene's suture runs along x at z = 30 from (0,0,30), 11 nodes 2 mm apart, node 0
// fixed. The cutter comes from below (forward = +z, tip at z = 32, hinge 8 mm lower), blades
// opening along y; its blade plane x = 11 crosses segment 5 (nodes 5-6).
struct CutterScene {
  Model model = GridModel(GridMesh(Vec3(0, 0, 0), {2, 2, 2}, 1.0),
                          [](const Vec3& p) { return p.z() < 0.01; });
  InputFrame Cutter(double jaw) const {
    return ToolInput(model, "cutter", Vec3(11.0, 0, 32.0), Vec3(0, 1, 0), Vec3(0, 0, 1), jaw, 0);
  }
};

State CutOnce(const Model& m, const CutterScene& scene, State s) {
  sim::Workspace ws;
  sim::BuildWorkspace(m, s, &ws);
  sim::Step(m, scene.Cutter(0.8), &s, &ws);
  EXPECT_TRUE(EventsOf(s, "thread_cut").empty());  // not yet past cut_at_jaw
  sim::Step(m, scene.Cutter(0.95), &s, &ws);
  return s;
}

TEST(ThreadCutter, LeavesExactlyTheBoneSidePart) {
  CutterScene scene;
  const Model& m = scene.model;
  State s0 = MakeInitialState(m);
  // A grasp on node 8 (free side) and one on node 2 (bone side).
  for (std::int32_t node : {8, 2}) {
    SpringConstraint c;
    c.tag = "grasp";
    c.a.kind = ConstraintEnd::Kind::kThread;
    c.a.index = 0;
    c.a.nodes = {node, -1, -1, -1};
    c.a.weights = {1, 0, 0, 0};
    c.b.kind = ConstraintEnd::Kind::kWorld;
    c.b.offset_mm = s0.threads[0].x.col(node);
    physics::AddConstraint(&s0, c);
  }
  const State s = CutOnce(m, scene, s0);
  const std::vector<Event> cuts = EventsOf(s, "thread_cut");
  ASSERT_EQ(cuts.size(), 1u);
  EXPECT_EQ(DetailInt(cuts[0].detail, "segment"), 5);
  EXPECT_EQ(DetailInt(cuts[0].detail, "cutting_point"), 6);
  EXPECT_EQ(DetailInt(cuts[0].detail, "removed_nodes"), 5);
  for (int n = 0; n < 11; ++n) EXPECT_EQ(s.threads[0].node_alive[n], n <= 5 ? 1 : 0) << n;
  ASSERT_EQ(s.constraints.size(), 1u);  // the grasp on node 8 went with its node
  EXPECT_EQ(s.constraints[0].a.nodes[0], 2);
}

TEST(ThreadCutter, TheBoneSideIsWhereverTheAnchorIs) {
  CutterScene scene;
  scene.model.threads[0].fixed_nodes = {10};
  const State s = CutOnce(scene.model, scene, MakeInitialState(scene.model));
  ASSERT_EQ(EventsOf(s, "thread_cut").size(), 1u);
  for (int n = 0; n < 11; ++n) EXPECT_EQ(s.threads[0].node_alive[n], n >= 6 ? 1 : 0) << n;
}

TEST(ThreadCutter, BothSidesHeldKeepsBothStrands) {
  CutterScene scene;
  scene.model.threads[0].fixed_nodes = {0, 10};
  const State s = CutOnce(scene.model, scene, MakeInitialState(scene.model));
  ASSERT_EQ(EventsOf(s, "thread_cut").size(), 1u);
  int dead = 0;
  for (int n = 0; n < 11; ++n) dead += s.threads[0].node_alive[n] == 0 ? 1 : 0;
  EXPECT_EQ(dead, 1);
  EXPECT_EQ(s.threads[0].node_alive[6], 0);
}

TEST(ThreadCutter, OnlyWhenTheBladesMeetAndOnlyThread) {
  CutterScene scene;
  const Model& m = scene.model;
  SceneRun run(m);
  auto& [s, ws] = run;
  // Closing but never past 0.9: no cut.
  for (double jaw : {0.0, 0.3, 0.6, 0.85, 0.89}) sim::Step(m, scene.Cutter(jaw), &s, &ws);
  for (std::uint8_t a : s.threads[0].node_alive) EXPECT_EQ(a, 1);
  // The scissors at the same place cut no thread.
  SceneRun run_s2(m);
  auto& [s2, ws2] = run_s2;
  InputFrame in = scene.Cutter(0.8);
  in.tools[0].instrument = m.FindInstrument("scissors");
  sim::Step(m, in, &s2, &ws2);
  in.tools[0].jaw = 0.95;
  sim::Step(m, in, &s2, &ws2);
  for (std::uint8_t a : s2.threads[0].node_alive) EXPECT_EQ(a, 1);
}

}  // namespace
}  // namespace arthrosim::instruments
