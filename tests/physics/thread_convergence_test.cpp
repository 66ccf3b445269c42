// Convergence of the thread Newton solve on the shoulder scene's suture (No. 2 FiberWire: EA 5 kN
// on 1 mm segments, 0.3 mg nodes, node 0 held by a 2000 N/mm anchor spring), a limb draped over
// a ball and pulled by a moving 5 N/mm grip spring: the retriever's situation (issues #14, #16,
// #17), the static equilibrium of a tensioned limb over a frictionless ball (the analytic
// tension), and the independence of the solves of separate threads.
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
  int substeps = 0;           // (sub)steps kept, over all steps
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
PullResult Pull(int steps, bool second, int substep_levels = 0) {
  std::vector<ThreadModel> models{Suture(Vec3(0, 0, 0))};
  if (second) models.push_back(Suture(Vec3(200, 0, 0)));
  std::vector<ThreadState> states;
  for (const ThreadModel& m : models) states.push_back(RestState(m));
  ThreadWorkspace ws;
  InitThreadWorkspace(models, &ws);
  ws.params.max_substep_levels = substep_levels;
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
    r.substeps += ws.last.substeps;
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

// Adaptive substeps (thread_solver.max_substep_levels 1: a step whose solve ends unconverged is
// redone from its start as two steps of dt / 2, the grip's anchor held at the step's end): the
// gripped node of the slack limb follows its grip (0.0066 mm behind instead of 0.48 mm). The
// unconverged solves are not fewer (9 of 83 kept substeps; with 2 / 3 / 4 levels 29 of 106,
// 58 of 139, 21 of 135), so the reproducer above stays disabled and the option off by default.
TEST(ThreadConvergence, OneSubstepLevelKeepsTheSlackLimbWithItsGrip) {
  const int steps = 75;
  const PullResult off = Pull(steps, false, 0);
  const PullResult on = Pull(steps, false, 1);
  std::printf(
      "pull, substep levels 0 / 1: %d / %d unconverged, %d / %d substeps kept, %d / %d Newton "
      "iterations, worst slack lag %.4f / %.4f mm, grip %.3f / %.3f N\n",
      off.unconverged, on.unconverged, off.substeps, on.substeps, off.newton, on.newton,
      off.worst_lag_mm, on.worst_lag_mm, off.final_grip_n, on.final_grip_n);
  EXPECT_EQ(off.substeps, steps);
  EXPECT_GT(on.substeps, steps);  // some steps were split
  EXPECT_LT(on.worst_lag_mm, 0.02);
  // The same end: taut, the grip's pull reaching the anchor.
  EXPECT_NEAR(on.final_grip_n, off.final_grip_n, 1e-3 * off.final_grip_n);
  EXPECT_NEAR(on.final_anchor_n, on.final_grip_n, 0.05 * on.final_grip_n);
}

struct PulleyResult {
  int unconverged = 0;        // solves stopped by the iteration cap, over all steps
  double max_strain = 0;      // largest |l / L - 1| at the end
  double grip_n = 0;          // grip spring force at the end, N
  double anchor_n = 0;        // anchor spring force at the end, N
  double tension_n = 0;       // analytic tension, N
  double max_speed_mm_s = 0;  // largest node speed at the end
};

// A limb wrapped half round a frictionless ball (radius 10 mm, no gravity): two 20 mm legs
// joined by a semicircle of 32 segments, node 0 held by the anchor spring (2000 N/mm) where it
// lies, the last node by a grip spring (5 N/mm) whose anchor is `pull_mm` beyond it along the
// leg. At static equilibrium the tension is uniform (the ball pushes only along its normals)
// and the springs and the chain are in series: T = pull / (1 / k_anchor + 1 / k_grip + L / EA
// + the compliance of the arc sinking into the 1000 N/mm contact planes, 0.15 % of the sum).
PulleyResult Pulley(int steps, double pull_mm) {
  const double r = 10, ea_n = 5000, ka = 2000, kg = 5, kc = 1000;
  std::vector<Vec3> pts;
  for (int i = 0; i <= 20; ++i) pts.push_back(Vec3(-r, 0, -20 + i));
  for (int i = 1; i <= 32; ++i) {
    const double a = units::kPi * (1 - i / 32.0);
    pts.push_back(Vec3(r * std::cos(a), 0, r * std::sin(a)));
  }
  for (int i = 1; i <= 20; ++i) pts.push_back(Vec3(r, 0, -i));
  ThreadModel m = Suture(Vec3::Zero());
  m.initial.nodes.resize(3, static_cast<Eigen::Index>(pts.size()));
  m.initial.edges.clear();
  for (std::size_t i = 0; i < pts.size(); ++i) m.initial.nodes.col(i) = pts[i];
  for (std::size_t i = 0; i + 1 < pts.size(); ++i)
    m.initial.edges.push_back({static_cast<std::int32_t>(i), static_cast<std::int32_t>(i + 1)});
  m.stretch_stiffness_n = ea_n;
  const int last = static_cast<int>(pts.size()) - 1;
  std::vector<ThreadModel> models{m};
  std::vector<ThreadState> states{RestState(m)};
  ThreadWorkspace ws;
  InitThreadWorkspace(models, &ws);
  double length = 0;
  for (double l : ws.rest[0].rest_length_mm) length += l;
  PulleyResult res;
  // The arc sinks T dtheta / kc at each of its nodes (dtheta = pi / 32), so its path is
  // shorter by pi^2 T / (32 kc).
  res.tension_n = pull_mm / (1 / ka + 1 / kg + length / ea_n + units::kPi * units::kPi / (32 * kc));
  SpringSet springs;
  for (int step = 0; step < steps; ++step) {
    ContactSet contacts;
    BallContacts(0, states[0], Vec3::Zero(), r, &contacts);
    for (PointContact& c : contacts) c.stiffness_n_per_mm = kc;
    springs.clear();
    PointSpring anchor = NodeSpring(0, 0, ka);
    anchor.anchor_mm = pts.front();
    springs.push_back(anchor);
    PointSpring grip = NodeSpring(0, last, kg);
    grip.anchor_mm = pts.back() + Vec3(0, 0, -pull_mm);
    springs.push_back(grip);
    StepThreads(models, kDt, Vec3::Zero(), &contacts, &springs, &states, &ws);
    res.unconverged += ws.last.unconverged_solves;
  }
  for (int i = 0; i < last; ++i) {
    const double l = (states[0].x.col(i + 1) - states[0].x.col(i)).norm();
    res.max_strain = std::max(res.max_strain, std::abs(l / ws.rest[0].rest_length_mm[i] - 1));
  }
  for (int i = 0; i <= last; ++i)
    res.max_speed_mm_s = std::max(res.max_speed_mm_s, states[0].v.col(i).norm());
  res.grip_n = springs[1].force_n.norm();
  res.anchor_n = springs[0].force_n.norm();
  return res;
}

// The limb over the ball reaches static equilibrium in which the chain keeps its length (strain
// below 1e-4) and the grip carries the analytic tension, equal to the anchor's.
TEST(ThreadConvergence, LimbOverFrictionlessBallCarriesTheAnalyticTension) {
  const int steps = 50;  // 1 s
  const PulleyResult r = Pulley(steps, 0.05);
  std::printf(
      "pulley: %d of %d solves unconverged, strain %.2e, grip %.5f N, anchor %.5f N, analytic "
      "%.5f N, speed %.2e mm/s\n",
      r.unconverged, steps, r.max_strain, r.grip_n, r.anchor_n, r.tension_n, r.max_speed_mm_s);
  EXPECT_EQ(r.unconverged, 0);
  EXPECT_LT(r.max_strain, 1e-4);
  EXPECT_LT(r.max_speed_mm_s, 1e-3);
  EXPECT_NEAR(r.grip_n, r.tension_n, 1e-3 * r.tension_n);
  EXPECT_NEAR(r.anchor_n, r.grip_n, 1e-3 * r.grip_n);
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
