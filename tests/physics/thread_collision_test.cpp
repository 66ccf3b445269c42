#include "arthrosim/physics/thread_collision.h"

#include <gtest/gtest.h>

#include <cmath>

#include "arthrosim/core/rng.h"
#include "arthrosim/core/units.h"
#include "arthrosim/physics/thread_chain.h"
#include "arthrosim/physics/thread_geometry.h"
#include "thread_test_util.h"

namespace arthrosim::physics {
namespace {

using testing::NodeSpring;
using testing::PassThrough;
using testing::PolylineThread;
using testing::RestState;

const Vec3 kGravity(0, 0, -units::kStandardGravityMmS2);

TEST(ThreadGeometry, ClosestPointsMatchBruteForce) {
  std::uint64_t rng = 7;
  auto r = [&] { return 4 * NextUniform(&rng) - 2; };
  for (int trial = 0; trial < 300; ++trial) {
    const Vec3 a0(r(), r(), r()), a1(r(), r(), r()), b0(r(), r(), r());
    Vec3 b1(r(), r(), r());
    if (trial % 10 == 0) b1 = b0 + (a1 - a0);  // parallel
    const SegmentClosest c = ClosestPointsSegments(a0, a1, b0, b1);
    double best = 1e30;
    for (int i = 0; i <= 200; ++i)
      for (int j = 0; j <= 200; ++j)
        best = std::min(best,
                        ((a0 + (a1 - a0) * (i / 200.0)) - (b0 + (b1 - b0) * (j / 200.0))).norm());
    EXPECT_LE(c.distance, best + 1e-12);
    EXPECT_GT(c.distance, best - 0.03);
    EXPECT_NEAR((c.p - c.q).norm(), c.distance, 1e-12);
  }
}

TEST(ThreadGeometry, SweptTestFindsCrossing) {
  // Segment b sweeps down through segment a in one step.
  SweptSegments m{{-1, 0, 0}, {1, 0, 0}, {0, -1, 1},  {0, 1, 1},
                  {-1, 0, 0}, {1, 0, 0}, {0, -1, -1}, {0, 1, -1}};
  SweptResult r = SweptSegmentTest(m, 1e-6, 1);
  EXPECT_TRUE(r.crosses);
  EXPECT_NEAR(r.time, 0.5, 1e-9);
  EXPECT_NEAR(r.min_distance, 0, 1e-9);
  // Passing beside the end of a: no crossing.
  m.b0_start.x() = m.b1_start.x() = m.b0_end.x() = m.b1_end.x() = 1.5;
  r = SweptSegmentTest(m, 1e-6, 4);
  EXPECT_FALSE(r.crosses);
  EXPECT_NEAR(r.min_distance, 0.5, 1e-9);
}

TEST(ThreadCollision, OverlappingPairsMatchesAllPairs) {
  std::uint64_t rng = 3;
  std::vector<Box3> boxes;
  for (int i = 0; i < 200; ++i) {
    Vec3 c(20 * NextUniform(&rng), 20 * NextUniform(&rng), 20 * NextUniform(&rng));
    boxes.push_back(Box3{c, c + Vec3(2, 2, 2) * NextUniform(&rng)});
  }
  boxes.push_back(boxes[5]);  // exact tie
  std::vector<std::array<int, 2>> ref;
  for (int i = 0; i < static_cast<int>(boxes.size()); ++i)
    for (int j = i + 1; j < static_cast<int>(boxes.size()); ++j)
      if ((boxes[i].min.array() <= boxes[j].max.array()).all() &&
          (boxes[j].min.array() <= boxes[i].max.array()).all())
        ref.push_back({i, j});
  EXPECT_EQ(OverlappingPairs(boxes), ref);
}

// Runs the step loop and checks every segment pair of every step for a pass-through.
struct CrossingRun {
  std::vector<ThreadModel> models;
  std::vector<ThreadState> states;
  ThreadWorkspace ws;
  int crossings = 0;
  double min_distance = 1e30;  // between segments of different threads, over step ends
  int frozen = 0;

  void Step(SpringSet* springs) {
    const std::vector<ThreadState> before = states;
    StepThreads(models, 0.02, kGravity, nullptr, springs, &states, &ws);
    frozen += ws.last.frozen_nodes;
    struct Seg {
      int t, i;
    };
    std::vector<Seg> segs;
    for (int t = 0; t < static_cast<int>(states.size()); ++t)
      for (int i = 0; i + 1 < states[t].x.cols(); ++i) segs.push_back({t, i});
    for (std::size_t p = 0; p < segs.size(); ++p) {
      for (std::size_t q = p + 1; q < segs.size(); ++q) {
        const Seg a = segs[p], b = segs[q];
        if (a.t == b.t && std::abs(a.i - b.i) < 2) continue;
        const Points &xa0 = before[a.t].x, &xb0 = before[b.t].x;
        const Points &xa1 = states[a.t].x, &xb1 = states[b.t].x;
        if (PassThrough(xa0.col(a.i), xa0.col(a.i + 1), xb0.col(b.i), xb0.col(b.i + 1),
                        xa1.col(a.i), xa1.col(a.i + 1), xb1.col(b.i), xb1.col(b.i + 1)))
          ++crossings;
        if (a.t != b.t)
          min_distance = std::min(
              min_distance,
              ClosestPointsSegments(xa1.col(a.i), xa1.col(a.i + 1), xb1.col(b.i), xb1.col(b.i + 1))
                  .distance);
      }
    }
  }
};

CrossingRun CrossedThreads() {
  CrossingRun run;
  ThreadModel a = PolylineThread({{-20, 0, 0}, {20, 0, 0}}, 40);
  a.fixed_nodes = {0, 40};
  ThreadModel b = PolylineThread({{0.3, -15, 5}, {-0.2, 15, 5}}, 30);
  b.name = "b";
  b.bend_stiffness_n_mm2 = 0.2;
  run.models = {a, b};
  run.states = {RestState(a), RestState(b)};
  InitThreadWorkspace(run.models, &run.ws);
  return run;
}

TEST(ThreadCollision, DroppedThreadDrapesWithoutPassingThrough) {
  // b is an arch whose ends are pinned below a: its crown falls ~5 mm onto a (reaching
  // ~300 mm/s, 6 mm per step, ten times the diameter) and must come to rest on it.
  CrossingRun run;
  ThreadModel a = PolylineThread({{-20, 0, 0}, {20, 0, 0}}, 40);
  a.fixed_nodes = {0, 40};
  ThreadModel b =
      PolylineThread({{0.3, -15, -10}, {0.1, -3, 5}, {-0.1, 3, 5}, {-0.3, 15, -10}}, 12);
  b.name = "b";
  b.fixed_nodes = {0, 36};
  b.bend_stiffness_n_mm2 = 0.2;
  b.damping_per_s = 2;
  run.models = {a, b};
  run.states = {RestState(a), RestState(b)};
  InitThreadWorkspace(run.models, &run.ws);
  for (int step = 0; step < 150; ++step) run.Step(nullptr);
  EXPECT_EQ(run.crossings, 0);
  // b's crown rests on a (contact distance 0.55 mm above a's axis), not below it.
  double crown = -1e30;
  for (int i = 0; i < run.states[1].x.cols(); ++i) crown = std::max(crown, run.states[1].x(2, i));
  EXPECT_GT(crown, 0.3);
  EXPECT_LT(crown, 1.0);
  EXPECT_GT(run.min_distance, 0.4);
  std::printf("drape: crown %.4f mm, min distance %.4f mm, frozen nodes %d\n", crown,
              run.min_distance, run.frozen);
}

TEST(ThreadCollision, FastPullThroughNeverTunnels) {
  // b's middle is yanked down at 1 m/s by a stiff spring: far more than the penalty can hold,
  // so the continuous check and the fail-safe must stop it.
  CrossingRun run = CrossedThreads();
  run.states[1].x.row(2).array() -= 4.0;  // start 1 mm above a
  SpringSet springs{NodeSpring(1, 15, 10)};
  for (int step = 0; step < 60; ++step) {
    springs[0].anchor_mm = Vec3(0, 0, 1.0 - 20.0 * std::min(step + 1, 15));
    run.Step(&springs);
  }
  // b may slide over a (frictionless) but never through it.
  EXPECT_EQ(run.crossings, 0);
  std::printf("pull-through: min distance %.4f mm, frozen nodes %d\n", run.min_distance,
              run.frozen);
}

TEST(ThreadCollision, SelfCollisionOfFoldedThread) {
  // A long thread dropped in a zig-zag onto itself: no segment passes through another.
  CrossingRun run;
  ThreadModel a = PolylineThread({{-10, 0, 0}, {10, 0, 0}}, 40);
  a.fixed_nodes = {0, 40};
  ThreadModel b = PolylineThread({{-6, -8, 3}, {-6, 8, 3}, {0, -8, 4}, {6, 8, 5}}, 16);
  b.name = "b";
  run.models = {a, b};
  run.states = {RestState(a), RestState(b)};
  InitThreadWorkspace(run.models, &run.ws);
  for (int step = 0; step < 100; ++step) run.Step(nullptr);
  EXPECT_EQ(run.crossings, 0);
}

}  // namespace
}  // namespace arthrosim::physics
