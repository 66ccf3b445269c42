// Convergence of the thread Newton solve on the shoulder scene's suture (No. 2 FiberWire: EA 5 kN
// on 1 mm segments, 0.3 mg nodes, node 0 held by a 2000 N/mm anchor spring), a limb draped over
// a ball and pulled by a moving 5 N/mm grip spring: the retriever's situation (issues #14, #16,
// #17), and the independence of the solves of separate threads.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "arthrosim/core/units.h"
#include "arthrosim/physics/thread_chain.h"
#include "thread_test_util.h"

namespace arthrosim::physics {
namespace {

using testing::NodeSpring;
using testing::OnThreadNode;
using testing::PolylineThread;
using testing::RestState;

const Vec3 kGravity(0, 0, -units::kStandardGravityMmS2);
constexpr double kDt = 0.02;  // the scene's step, s

// The scene's suture: 79 segments of 1 mm along three sides of a 26 mm square from `origin`
// (x, then y, then back along -x), lying flat, 80 nodes.
ThreadModel Suture(const Vec3& origin) {
  std::vector<Vec3> corners;
  for (int i = 0; i < 80; ++i)
    corners.push_back(origin + (i <= 26   ? Vec3(i, 0, 0)
                                : i <= 52 ? Vec3(26, i - 26, 0)
                                          : Vec3(26 - (i - 52), 26, 0)));
  ThreadModel m = PolylineThread(corners, 1);  // 80 nodes
  m.diameter_mm = 0.55;
  m.density_kg_m3 = 1300;
  m.stretch_stiffness_n = 5000;
  m.bend_stiffness_n_mm2 = 0;
  m.damping_per_s = 0;
  m.max_speed_mm_s = 500;
  return m;
}

// Contact planes of every node of thread `t` near the ball (centre c, radius r): the tangent plane
// at the node's closest point, 2 N/mm like the scene's bone contacts.
void BallContacts(int t, const ThreadState& st, const Vec3& c, double r, ContactSet* out) {
  for (int i = 0; i < st.x.cols(); ++i) {
    const Vec3 d = st.x.col(i) - c;
    const double dist = d.norm();
    if (dist > r + 1.0 || dist < 1e-9) continue;
    PointContact pc = OnThreadNode<PointContact>(t, i, 2.0);
    pc.normal = d / dist;
    pc.offset_mm = pc.normal.dot(c) + r;
    out->push_back(pc);
  }
}

struct PullResult {
  int unconverged = 0;        // solves stopped by the iteration cap, over all steps
  int newton = 0;             // Newton iterations, over all steps
  double worst_lag_mm = 0;    // largest grip-to-node distance while the limb was slack
  double final_grip_n = 0;    // grip spring force at the end, N
  double final_anchor_n = 0;  // anchor spring force at the end, N
  Points final_x;             // thread 0 at the end
};

// Thread 0 lies around a ball of radius 20 that rises 3 mm through the middle of its square; its
// node 47 is pulled by a grip moving along +x at 20 mm/s for 0.85 s (the limb from the anchor,
// 47 mm of arc, goes taut over the ball at ~0.8 s), then held; node 0 is held by the anchor
// spring. With `second`, a
// second, independent suture lies 200 mm away with its free end yanked by a stiff spring to a
// far target every step (its own solve hard), and with the same anchor.
PullResult Pull(int steps, bool second) {
  std::vector<ThreadModel> models{Suture(Vec3(0, 0, 0))};
  if (second) models.push_back(Suture(Vec3(200, 0, 0)));
  std::vector<ThreadState> states;
  for (const ThreadModel& m : models) states.push_back(RestState(m));
  ThreadWorkspace ws;
  InitThreadWorkspace(models, &ws);
  const Vec3 ball(13, 13, -17);
  const Vec3 grip0 = states[0].x.col(47);
  const Vec3 grip_velocity(20, 0, 0);  // mm/s
  PullResult r;
  for (int step = 0; step < steps; ++step) {
    ContactSet contacts;
    for (int t = 0; t < static_cast<int>(models.size()); ++t)
      BallContacts(t, states[t], t == 0 ? ball : ball + Vec3(200, 0, 0), 20, &contacts);
    SpringSet springs;
    for (int t = 0; t < static_cast<int>(models.size()); ++t) {
      PointSpring anchor = NodeSpring(t, 0, 2000);
      anchor.anchor_mm = models[t].initial.nodes.col(0);
      springs.push_back(anchor);
    }
    PointSpring grip = NodeSpring(0, 47, 5);
    const double t = std::min(kDt * (step + 1), 0.85);  // s
    grip.anchor_mm = grip0 + grip_velocity * t;
    springs.push_back(grip);
    if (second) {
      // The free end of the second suture is flung 30 mm back and forth each step.
      PointSpring yank = NodeSpring(1, 79, 50);
      yank.anchor_mm = models[1].initial.nodes.col(79) + Vec3(0, 0, step % 2 ? 30 : -30);
      springs.push_back(yank);
    }
    StepThreads(models, kDt, kGravity, &contacts, &springs, &states, &ws);
    r.unconverged += ws.last.unconverged_solves;
    r.newton += ws.last.newton_iterations;
    // Arc from the anchor to node 47 is 47 mm: slack while the grip is well closer than that
    // (38.5 mm at 0.6 s, with the detour over the ball).
    const Vec3 held = states[0].x.col(47);
    if (t <= 0.6) r.worst_lag_mm = std::max(r.worst_lag_mm, (held - grip.anchor_mm).norm());
    r.final_grip_n = springs[springs.size() - (second ? 2 : 1)].force_n.norm();
    r.final_anchor_n = springs[0].force_n.norm();
  }
  r.final_x = states[0].x;
  return r;
}

// Open (docs/operations.md, "Where the retriever's pull goes"): 9 of the 75 solves stop at the
// iteration cap (the first steps of the pull on the straight, untensioned limb, and steps in
// which the line search's length correction swings the free tail past its speed barrier, so
// every iteration accepts only half its step) and the gripped node lags the grip by 0.48 mm
// while the limb is slack. Enable when the chain solve converges.
TEST(ThreadConvergence, DISABLED_PulledLimbOverBallConvergesAndFollowsTheGrip) {
  const int steps = 75;  // 1.5 s: 0.85 s of pull, then 0.65 s held
  const PullResult r = Pull(steps, false);
  std::printf(
      "pull: %d of %d solves unconverged, %d Newton iterations, worst slack lag %.4f mm, "
      "grip %.3f N, anchor %.3f N\n",
      r.unconverged, steps, r.newton, r.worst_lag_mm, r.final_grip_n, r.final_anchor_n);
  EXPECT_EQ(r.unconverged, 0);
  // Slack limb: only the limb's inertia and the ball resist; a lag of 0.2 mm is 1 N of grip.
  EXPECT_LT(r.worst_lag_mm, 0.2);
  // Taut at the end: the grip's pull reaches the anchor (frictionless ball, light limb).
  EXPECT_GT(r.final_grip_n, 1.0);
  EXPECT_NEAR(r.final_anchor_n, r.final_grip_n, 0.05 * r.final_grip_n);
}

// Separate threads are separate groups of the Newton solve, each with its own active set, line
// search and convergence: the pulled limb moves as it does alone (to rounding) beside a suture
// whose own solve is hard. With one line-search factor for all threads it differed by 0.52 mm.
TEST(ThreadConvergence, AHardThreadDoesNotSlowAnIndependentOne) {
  const int steps = 60;
  const PullResult alone = Pull(steps, false);
  const PullResult both = Pull(steps, true);
  double diff = 0;
  for (int i = 0; i < alone.final_x.cols(); ++i)
    diff = std::max(diff, (alone.final_x.col(i) - both.final_x.col(i)).norm());
  std::printf(
      "independent: pulled limb differs by %.3e mm with a yanked second suture (%d / %d "
      "unconverged solves alone / both)\n",
      diff, alone.unconverged, both.unconverged);
  EXPECT_LT(diff, 1e-6);
}

}  // namespace
}  // namespace arthrosim::physics
