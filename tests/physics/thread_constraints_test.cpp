#include <gtest/gtest.h>

#include <cmath>
#include <cstring>

#include "arthrosim/core/rng.h"
#include "arthrosim/core/units.h"
#include "arthrosim/physics/constraints.h"
#include "arthrosim/physics/thread_chain.h"
#include "arthrosim/physics/thread_cut.h"
#include "thread_test_util.h"

namespace arthrosim::physics {
namespace {

using testing::PolylineThread;
using testing::RestState;

const Vec3 kGravity(0, 0, -units::kStandardGravityMmS2);

ConstraintEnd ThreadNode(int thread, int node) {
  ConstraintEnd e;
  e.kind = ConstraintEnd::Kind::kThread;
  e.index = thread;
  e.nodes = {node, -1, -1, -1};
  e.weights = {1, 0, 0, 0};
  return e;
}

ConstraintEnd ToolPoint(int slot, const Vec3& local) {
  ConstraintEnd e;
  e.kind = ConstraintEnd::Kind::kTool;
  e.index = slot;
  e.offset_mm = local;
  return e;
}

TEST(Constraints, AddFindRemoveKeepIdsSorted) {
  State s;
  SpringConstraint c;
  c.tag = "grasp";
  c.a = ThreadNode(0, 3);
  c.b = ToolPoint(1, Vec3::Zero());
  const std::int64_t g1 = AddConstraint(&s, c);
  c.tag = "suture";
  c.b = ThreadNode(0, 7);
  const std::int64_t s1 = AddConstraint(&s, c);
  c.tag = "grasp";
  const std::int64_t g2 = AddConstraint(&s, c);
  EXPECT_EQ(g1, 1);
  EXPECT_EQ(s1, 2);
  EXPECT_EQ(g2, 3);
  EXPECT_EQ(s.next_constraint_id, 4);
  EXPECT_EQ(FindConstraintsByTag(s, "grasp"), (std::vector<std::int64_t>{1, 3}));
  EXPECT_EQ(FindConstraintsByEnd(s, ConstraintEnd::Kind::kThread, 0, 7),
            (std::vector<std::int64_t>{2, 3}));
  EXPECT_EQ(FindConstraintsByEnd(s, ConstraintEnd::Kind::kTool, 1), (std::vector<std::int64_t>{1}));
  EXPECT_TRUE(RemoveConstraint(&s, 2));
  EXPECT_FALSE(RemoveConstraint(&s, 2));
  EXPECT_EQ(FindConstraint(s, 2), nullptr);
  ASSERT_NE(FindConstraint(s, 3), nullptr);
  EXPECT_EQ(FindConstraint(s, 3)->tag, "grasp");
  EXPECT_EQ(AddConstraint(&s, c), 4);  // ids are never reused
  for (std::size_t i = 1; i < s.constraints.size(); ++i)
    EXPECT_LT(s.constraints[i - 1].id, s.constraints[i].id);
  c.stiffness_n_per_mm = -1;
  EXPECT_THROW(AddConstraint(&s, c), std::invalid_argument);
}

TEST(Constraints, EndPositionAndPointSprings) {
  State s;
  ThreadModel m = PolylineThread({{0, 0, 0}, {4, 0, 0}}, 4);
  s.threads.push_back(RestState(m));
  s.tools[0].pose.position_mm = Vec3(1, 2, 3);
  s.tools[0].pose.orientation = Quat(Eigen::AngleAxisd(units::kPi / 2, Vec3::UnitZ()));
  ConstraintEnd mid = ThreadNode(0, 1);
  mid.nodes = {1, 2, -1, -1};
  mid.weights = {0.25, 0.75, 0, 0};
  EXPECT_TRUE(EndPosition(s, mid).isApprox(Vec3(1.75, 0, 0)));
  const Vec3 tool_pt = EndPosition(s, ToolPoint(0, Vec3(1, 0, 0)));
  EXPECT_NEAR((tool_pt - Vec3(1, 3, 3)).norm(), 0, 1e-12);
  ConstraintEnd bad = ThreadNode(0, 9);
  EXPECT_THROW(EndPosition(s, bad), std::invalid_argument);
  bad = ThreadNode(2, 0);
  EXPECT_THROW(EndPosition(s, bad), std::invalid_argument);

  SpringConstraint knot;
  knot.tag = "knot";
  knot.a = ThreadNode(0, 0);
  knot.b = mid;
  knot.stiffness_n_per_mm = 2;
  knot.rest_length_mm = 0.5;
  AddConstraint(&s, knot);
  SpringConstraint grasp;
  grasp.a = ToolPoint(0, Vec3(1, 0, 0));
  grasp.b = ThreadNode(0, 4);
  AddConstraint(&s, grasp);
  const SpringSet springs = BuildPointSprings(s);
  ASSERT_EQ(springs.size(), 3u);  // knot: two thread sides; grasp: one
  EXPECT_EQ(springs[0].constraint_id, 1);
  EXPECT_TRUE(springs[0].anchor_mm.isApprox(Vec3(1.75, 0, 0)));
  EXPECT_EQ(springs[1].nodes[1], 2);
  EXPECT_TRUE(springs[1].anchor_mm.isApprox(Vec3(0, 0, 0)));
  EXPECT_EQ(springs[1].rest_length_mm, 0.5);
  EXPECT_EQ(springs[2].constraint_id, 2);
  EXPECT_NEAR((springs[2].anchor_mm - Vec3(1, 3, 3)).norm(), 0, 1e-12);
}

TEST(Constraints, ThreadFollowsToolThroughSpring) {
  ThreadModel m = PolylineThread({{0, 0, 0}, {20, 0, 0}}, 20);
  m.fixed_nodes = {0};
  m.bend_stiffness_n_mm2 = 0.1;
  m.damping_per_s = 1;
  State s;
  s.threads.push_back(RestState(m));
  std::vector<ThreadModel> models{m};
  ThreadWorkspace ws;
  InitThreadWorkspace(models, &ws);
  s.tools[0].pose.position_mm = Vec3(20, 0, 0);  // on the free end at t = 0
  SpringConstraint grasp;
  grasp.tag = "grasp";
  grasp.a = ToolPoint(0, Vec3::Zero());
  grasp.b = ThreadNode(0, 20);
  grasp.stiffness_n_per_mm = 5;
  const std::int64_t id = AddConstraint(&s, grasp);
  double worst = 0;
  for (int step = 0; step < 200; ++step) {
    // Tool circles at 6 mm radius around (14, 0, 0) in the x-z plane, 2 s period (~19 mm/s),
    // always within reach of the 20 mm thread anchored at the origin.
    const double phase = 2 * units::kPi * (step + 1) * 0.02 / 2.0;
    s.tools[0].pose.position_mm = Vec3(14 + 6 * std::cos(phase), 0, 6 * std::sin(phase));
    SpringSet springs = BuildPointSprings(s);
    StepThreads(models, 0.02, kGravity, nullptr, &springs, &s.threads, &ws);
    const double gap = (s.threads[0].x.col(20) - s.tools[0].pose.position_mm).norm();
    if (step > 10) worst = std::max(worst, gap);
    // The reported force is the spring's pull toward the tool point.
    const Vec3 pull = 5e3 * (s.tools[0].pose.position_mm - s.threads[0].x.col(20)) * 1e-3;
    EXPECT_NEAR((springs[0].force_n - pull).norm(), 0, 1e-9 + 1e-9 * pull.norm());
  }
  EXPECT_LT(worst, 0.05) << "grasped node lags the tool";
  // Released: the thread falls away from the tool.
  ASSERT_TRUE(RemoveConstraint(&s, id));
  for (int step = 0; step < 20; ++step) {
    SpringSet springs = BuildPointSprings(s);
    StepThreads(models, 0.02, kGravity, nullptr, &springs, &s.threads, &ws);
  }
  EXPECT_GT((s.threads[0].x.col(20) - s.tools[0].pose.position_mm).norm(), 2.0);
}

TEST(ThreadCut, CutRemovesFreeSideAndItsConstraints) {
  ThreadModel m = PolylineThread({{0, 0, 0}, {10, 0, 0}}, 10);
  m.fixed_nodes = {0};
  State s;
  s.threads.push_back(RestState(m));
  SpringConstraint c;
  c.a = ThreadNode(0, 8);
  c.b = ToolPoint(0, Vec3::Zero());
  AddConstraint(&s, c);
  c.a = ThreadNode(0, 3);
  AddConstraint(&s, c);
  EXPECT_EQ(CutThreadAtSegment(m, &s.threads[0], 5), 5);  // nodes 6..10
  for (int i = 0; i <= 10; ++i) EXPECT_EQ(s.threads[0].node_alive[i], i <= 5 ? 1 : 0);
  EXPECT_EQ(RemoveConstraintsOnDeadThreadNodes(&s), 1);
  ASSERT_EQ(s.constraints.size(), 1u);
  EXPECT_EQ(s.constraints[0].id, 2);
  EXPECT_NEAR(ThreadLength(s.threads[0]), 5.0, 1e-12);
  // Anchored at the far end: the near side goes.
  ThreadModel m2 = m;
  m2.fixed_nodes = {10};
  ThreadState t2 = RestState(m2);
  EXPECT_EQ(CutThreadAtSegment(m2, &t2, 2), 3);  // nodes 0..2
  EXPECT_EQ(t2.node_alive[2], 0);
  EXPECT_EQ(t2.node_alive[3], 1);
  EXPECT_EQ(CutThreadFrom(&t2, 9), 2);
  EXPECT_THROW(CutThreadFrom(&t2, 11), std::invalid_argument);
  // The cut thread still steps.
  std::vector<ThreadModel> models{m};
  ThreadWorkspace ws;
  InitThreadWorkspace(models, &ws);
  for (int step = 0; step < 5; ++step)
    StepThreads(models, 0.02, kGravity, nullptr, nullptr, &s.threads, &ws);
  EXPECT_EQ(s.threads[0].x.col(8), m.initial.nodes.col(8));
  EXPECT_LT(s.threads[0].x(2, 5), -0.1);
}

// Random tool pulls on two threads with collision: the run used for stability and determinism.
struct PullRun {
  std::vector<ThreadModel> models;
  std::vector<ThreadState> states;
  ThreadWorkspace ws;
  double max_energy = 0;
  double max_speed = 0;
  double max_strain = 0;
  bool finite = true;
};

PullRun RandomPulls(int steps, std::uint64_t seed) {
  PullRun run;
  ThreadModel a = PolylineThread({{0, 0, 0}, {30, 0, 0}}, 40);
  a.fixed_nodes = {0};
  a.bend_stiffness_n_mm2 = 0.5;
  ThreadModel b = PolylineThread({{15, -15, 2}, {15, 15, 2}}, 30);
  b.name = "b";
  b.fixed_nodes = {0};
  run.models = {a, b};
  run.states = {RestState(a), RestState(b)};
  InitThreadWorkspace(run.models, &run.ws);
  std::uint64_t rng = seed;
  SpringSet springs(2);
  for (int k = 0; k < 2; ++k) {
    springs[k].target = PointContact::Target::kThread;
    springs[k].index = k;
    springs[k].weights = {1, 0, 0, 0};
    springs[k].stiffness_n_per_mm = 2;
  }
  for (int step = 0; step < steps; ++step) {
    if (step % 10 == 0) {
      for (int k = 0; k < 2; ++k) {
        const int n = static_cast<int>(run.states[k].x.cols());
        springs[k].nodes[0] = 1 + static_cast<int>(NextUniform(&rng) * (n - 1));
        springs[k].anchor_mm =
            Vec3(15, 0, 0) +
            Vec3(NextUniform(&rng) - 0.5, NextUniform(&rng) - 0.5, NextUniform(&rng) - 0.5) * 40.0;
      }
    }
    StepThreads(run.models, 0.02, kGravity, nullptr, &springs, &run.states, &run.ws);
    for (int k = 0; k < 2; ++k) {
      const ThreadState& st = run.states[k];
      run.finite = run.finite && st.x.allFinite() && st.v.allFinite();
      for (int i = 0; i < st.v.cols(); ++i)
        run.max_speed = std::max(run.max_speed, st.v.col(i).norm());
      for (int i = 0; i + 1 < st.x.cols(); ++i) {
        const double l0 = run.ws.rest[k].rest_length_mm[i];
        run.max_strain =
            std::max(run.max_strain, ((st.x.col(i + 1) - st.x.col(i)).norm() - l0) / l0);
      }
      run.max_energy =
          std::max(run.max_energy, ThreadEnergy(run.models[k], run.ws.rest[k], st, kGravity));
    }
  }
  return run;
}

TEST(ThreadStability, RandomToolPullsAtTwentyMs) {
  const PullRun run = RandomPulls(1000, 11);
  EXPECT_TRUE(run.finite);
  EXPECT_LE(run.max_speed, 500 * (1 + 1e-12));
  // Bound: kinetic energy at the speed cap + spring work over the 40 mm box + gravity over it,
  // for 41 nodes of ~0.23 ug each; far above physical, far below a blow-up.
  const double mass = 0.25 * units::kPi * 0.55 * 0.55 * 30 * 1300e-9;
  const double bound = 0.5 * mass * 500 * 500 + 0.5 * 2e3 * 70 * 70 + mass * 9810 * 70;
  EXPECT_LT(run.max_energy, bound);
  // Pulls of up to ~80 N on EA = 5 kN (1.6 %) with a 1 % strain limit: never near the ~5 %
  // at which FiberWire fails; a blow-up would show tens of percent.
  EXPECT_LT(run.max_strain, 0.03);
  // The strain limit is a projection solved to 1e-12 of the length: no transient stretch
  // beyond 1 % (the elastic strain of the largest pulls is ~1.6 %).
  EXPECT_LE(run.max_strain, 0.01 + 1e-9);
  std::printf("1000 random-pull steps: max energy %.3e uJ (bound %.3e), max strain %.3e\n",
              run.max_energy, bound, run.max_strain);
}

TEST(ThreadDeterminism, SameInputsBitIdentical) {
  const PullRun a = RandomPulls(150, 5);
  const PullRun b = RandomPulls(150, 5);
  for (int k = 0; k < 2; ++k) {
    ASSERT_EQ(a.states[k].x.size(), b.states[k].x.size());
    EXPECT_EQ(0, std::memcmp(a.states[k].x.data(), b.states[k].x.data(),
                             sizeof(double) * a.states[k].x.size()));
    EXPECT_EQ(0, std::memcmp(a.states[k].v.data(), b.states[k].v.data(),
                             sizeof(double) * a.states[k].v.size()));
  }
  const PullRun c = RandomPulls(150, 6);
  EXPECT_NE(0, std::memcmp(a.states[0].x.data(), c.states[0].x.data(),
                           sizeof(double) * a.states[0].x.size()));
}

}  // namespace
}  // namespace arthrosim::physics
