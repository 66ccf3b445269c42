// Sliding constraint ends: a thread held by stitch springs whose thread ends move along the
// chain with Coulomb friction. Analytic slide of one end, then a thread pulled through four
// stitches: slides above the total friction, holds below it, stays in the bite at 20 N, keeps
// its energy bounded and repeats bit for bit.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>

#include "arthrosim/core/parallel.h"
#include "arthrosim/physics/constraints.h"
#include "arthrosim/physics/thread_chain.h"
#include "thread_test_util.h"

namespace arthrosim::physics {
namespace {

using testing::PolylineThread;
using testing::RestState;

ConstraintEnd WorldPoint(const Vec3& p) {
  ConstraintEnd e;
  e.kind = ConstraintEnd::Kind::kWorld;
  e.offset_mm = p;
  return e;
}

TEST(SlidingEnd, ThreadPointEndRoundTrip) {
  const ConstraintEnd e = ThreadPointEnd(2, 4.25);
  EXPECT_EQ(e.nodes[0], 4);
  EXPECT_EQ(e.nodes[1], 5);
  EXPECT_DOUBLE_EQ(e.weights[0], 0.75);
  EXPECT_DOUBLE_EQ(ThreadEndParameter(e), 4.25);
  const ConstraintEnd n = ThreadPointEnd(0, 3.0);
  EXPECT_EQ(n.nodes[1], -1);
  EXPECT_DOUBLE_EQ(ThreadEndParameter(n), 3.0);
  EXPECT_THROW(ThreadPointEnd(0, -1.0), std::invalid_argument);
  ConstraintEnd odd = e;
  odd.nodes[1] = 7;
  EXPECT_THROW(ThreadEndParameter(odd), std::invalid_argument);
}

TEST(SlidingEnd, SlidesUntilThePullAlongTheThreadEqualsTheFriction) {
  State s;
  s.threads.push_back(RestState(PolylineThread({{0, 0, 0}, {10, 0, 0}}, 10)));
  SpringConstraint c;
  c.a = ThreadPointEnd(0, 5.0);
  c.b = WorldPoint(Vec3(7, 0.3, 0));
  c.stiffness_n_per_mm = 5;
  c.slide_friction_n = 2;
  const std::int64_t id = AddConstraint(&s, c);
  SpringConstraint fixed = c;  // the same spring without sliding stays put
  fixed.slide_friction_n = -1;
  const std::int64_t fixed_id = AddConstraint(&s, fixed);
  EXPECT_EQ(SlideConstraintEnds(&s), 1);
  // Pull along x: 5 N/mm * 2 mm = 10 N; 8 N above the friction slides 8 / 5 = 1.6 mm.
  EXPECT_NEAR(ThreadEndParameter(FindConstraint(s, id)->a), 6.6, 1e-12);
  EXPECT_DOUBLE_EQ(ThreadEndParameter(FindConstraint(s, fixed_id)->a), 5.0);
  // Now the pull along the thread is the friction: nothing moves.
  EXPECT_EQ(SlideConstraintEnds(&s), 0);
  // A pull toward node 0 beyond the chain's start stops at node 0.
  SpringConstraint back = c;
  back.b = WorldPoint(Vec3(-30, 0, 0));
  const std::int64_t back_id = AddConstraint(&s, back);
  SlideConstraintEnds(&s);
  EXPECT_DOUBLE_EQ(ThreadEndParameter(FindConstraint(s, back_id)->a), 0.0);
}

// A 30-segment thread (1 mm segments) through a bite of four stitch springs at nodes 10..13
// (world points: the tendon held still), node 0 optionally fixed, node 30 pulled toward +x by a
// soft spring whose force hardly changes as the thread moves.
struct PullRig {
  std::vector<ThreadModel> models;
  State s;
  ThreadWorkspace ws;
  std::vector<std::int64_t> stitches;
  double pull_n;
  PullRig(double pull, double friction_n, const std::vector<Vec3>& corners, int per_leg,
          bool fix_start)
      : pull_n(pull) {
    ThreadModel m = PolylineThread(corners, per_leg);
    m.damping_per_s = 5;
    if (fix_start) m.fixed_nodes = {0};
    models.push_back(m);
    s.threads.push_back(RestState(m));
    InitThreadWorkspace(models, &ws);
    const int last = static_cast<int>(m.initial.nodes.cols()) - 1;
    for (int k = 0; k < 4; ++k) {
      const int node = 10 + k;
      SpringConstraint c;
      c.tag = "stitch";
      c.a = ThreadPointEnd(0, node);
      c.b = WorldPoint(m.initial.nodes.col(node));
      c.stiffness_n_per_mm = 5;
      c.slide_friction_n = friction_n;
      stitches.push_back(AddConstraint(&s, c));
    }
    SpringConstraint p;
    p.tag = "pull";
    p.a = ThreadPointEnd(0, last);
    p.b = WorldPoint(m.initial.nodes.col(last) + Vec3(200, 0, 0));
    p.stiffness_n_per_mm = pull / 200;
    AddConstraint(&s, p);
  }
  void Step() {
    SpringSet springs = BuildPointSprings(s);
    StepThreads(models, 0.01, Vec3::Zero(), nullptr, &springs, &s.threads, &ws);
    SlideConstraintEnds(&s);
  }
  Vec3 End() const { return s.threads[0].x.col(s.threads[0].x.cols() - 1); }
  double Param(int k) const { return ThreadEndParameter(FindConstraint(s, stitches[k])->a); }
  double WorstStretchMm() const {
    double worst = 0;
    for (const std::int64_t id : stitches) {
      const SpringConstraint* c = FindConstraint(s, id);
      worst = std::max(worst, (EndPosition(s, c->a) - EndPosition(s, c->b)).norm());
    }
    return worst;
  }
  double KineticEnergyMj() const {  // 0.5 m v^2, kg (mm/s)^2 -> mJ
    const ThreadModel& m = models[0];
    const double area_mm2 = 3.14159265358979 * 0.25 * m.diameter_mm * m.diameter_mm;
    const double node_kg = m.density_kg_m3 * area_mm2 * 1.0 * 1e-9;
    return 0.5 * node_kg * s.threads[0].v.colwise().squaredNorm().sum() * 1e-3;
  }
};

const std::vector<Vec3> kStraight{{0, 0, 0}, {30, 0, 0}};

TEST(SlidingEnd, ThreadSlidesThroughTheBiteAboveTheFriction) {
  // Four stitches at 0.5 N: 2 N hold the thread; a 3 N pull draws it through.
  PullRig rig(3.0, 0.5, kStraight, 30, false);
  const double end0 = rig.End().x();
  for (int k = 0; k < 200; ++k) rig.Step();
  const double moved_mm = rig.End().x() - end0;
  EXPECT_GT(moved_mm, 3.0) << "the thread ran through the bite";
  // The stitch points moved back along the thread by as much as the thread moved forward.
  EXPECT_NEAR(10.0 - rig.Param(0), moved_mm, 0.3);
  EXPECT_LT(rig.WorstStretchMm(), 0.2);
  EXPECT_TRUE(rig.s.threads[0].x.allFinite());
}

TEST(SlidingEnd, ThreadHoldsBelowTheFriction) {
  PullRig rig(1.5, 0.5, kStraight, 30, false);
  for (int k = 0; k < 100; ++k) rig.Step();
  const Vec3 end_1s = rig.End();
  for (int k = 0; k < 100; ++k) rig.Step();
  EXPECT_LT((rig.End() - end_1s).norm(), 0.01) << "at rest after the first second";
  EXPECT_LT(rig.End().x() - 30.0, 0.5) << "only the springs' elastic give";
  for (int k = 0; k < 4; ++k) EXPECT_NEAR(rig.Param(k), 10 + k, 0.5);
}

TEST(SlidingEnd, NoPullOutAtTwentyNewtonsAndEnergyBounded) {
  // The thread's start is held (the anchor) and it has 4 mm of slack before the bite (a 10 mm
  // V over 6 mm, 1 mm segments): 20 N on the free limb takes up the slack through the bite,
  // then the stitches hold.
  PullRig rig(20.0, 0.5,
              {{0, 0, 0}, {3, 0, 4}, {6, 0, 0}, {11, 0, 0}, {16, 0, 0}, {21, 0, 0}, {26, 0, 0}}, 5,
              true);
  const int last = static_cast<int>(rig.s.threads[0].x.cols()) - 1;
  double worst_ke_mj = 0;
  for (int k = 0; k < 300; ++k) {
    rig.Step();
    ASSERT_TRUE(rig.s.threads[0].x.allFinite()) << "step " << k;
    worst_ke_mj = std::max(worst_ke_mj, rig.KineticEnergyMj());
  }
  // Bounded by the pull's work over the slack taken up (20 N * 4 mm = 80 mJ).
  EXPECT_LT(worst_ke_mj, 80.0);
  EXPECT_LT(rig.KineticEnergyMj(), 1e-3) << "at rest";
  for (const std::int64_t id : rig.stitches) ASSERT_NE(FindConstraint(rig.s, id), nullptr);
  for (int k = 0; k < 4; ++k) {
    EXPECT_GT(rig.Param(k), 1.0) << "stitch " << k << " stays on the thread";
    EXPECT_LT(rig.Param(k), last - 1.0);
  }
  EXPECT_LT(rig.WorstStretchMm(), 20.0 / (4 * 5) + 0.5);
  // The slack was pulled through: the stitch points now lie further toward the anchor.
  EXPECT_LT(rig.Param(0), 10 - 2.0);
  const Points& x = rig.s.threads[0].x;
  double seg_min = 1e9, seg_max = 0;
  for (int n = 0; n < last; ++n) {
    const double l = (x.col(n + 1) - x.col(n)).norm();
    seg_min = std::min(seg_min, l);
    seg_max = std::max(seg_max, l);
  }
  const double rest_mm =
      (rig.models[0].initial.nodes.col(1) - rig.models[0].initial.nodes.col(0)).norm();
  EXPECT_LT(seg_max / rest_mm - 1.0, 0.01) << "thread strain <= 1 %";
}

TEST(SlidingEnd, BitIdenticalRerunsAndThreadCounts) {
  const auto run = [](int threads) {
    SetThreadCount(threads);
    PullRig rig(3.0, 0.5, kStraight, 30, false);
    for (int k = 0; k < 80; ++k) rig.Step();
    SetThreadCount(1);
    return rig.s;
  };
  const State a = run(1), b = run(1), c = run(2);
  EXPECT_TRUE(BitwiseEqual(a, b));
  EXPECT_TRUE(BitwiseEqual(a, c));
  EXPECT_NE(ThreadEndParameter(a.constraints[0].a), 10.0) << "it did slide";
}

}  // namespace
}  // namespace arthrosim::physics
