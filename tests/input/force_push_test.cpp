// Force-profile pushes: the admittance law against a fake linear-spring tissue, ramps, limits,
// the excursion carried into later actions, validation and determinism.
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "arthrosim/core/error.h"
#include "arthrosim/core/scope_aim.h"
#include "arthrosim/core/units.h"
#include "arthrosim/input/script_source.h"
#include "test_model.h"

namespace arthrosim::input {
namespace {

using testing::MakeTestModel;

constexpr double kDt = 0.01;

ScriptOptions Opt() {
  ScriptOptions o;
  o.dt_s = kDt;
  return o;
}

// The grasper enters (1 s) and then pushes; the force push starts at t = 1 s.
std::string Script(const std::string& push, const std::string& after = "") {
  return "name: fp\nslot0:\n"
         "  - pick: {instrument: grasper, toward: tear_edge_center, depth: 10, duration: 1.0}\n"
         "  - push: " +
         push + "\n" + after;
}

// Runs the source from step 1 to t_end with a fake tissue: a linear spring of stiffness k (N/mm)
// along the tool axis, starting at the push's start; the tool feels the reaction -k d axis.
struct SpringRun {
  Vec3 start = Vec3::Zero();
  Vec3 axis = Vec3::UnitZ();
  std::vector<double> t, depth_mm, pressing_n;
  std::vector<InputFrame> frames;
};

SpringRun RunSpring(ScriptSource* s, double k_n_per_mm, double t_end, double t_push = 1.0) {
  SpringRun r;
  InputFrame f;
  s->Frame(static_cast<std::int64_t>(std::llround(t_push / kDt)), t_push, &f);
  r.start = f.tools[0].pose.position_mm;
  r.axis = f.tools[0].pose.orientation * Vec3::UnitZ();
  const std::int64_t n = std::llround(t_end / kDt);
  for (std::int64_t step = 1; step <= n; ++step) {
    const double t = static_cast<double>(step) * kDt;
    s->Frame(step, t, &f);
    const double d = (f.tools[0].pose.position_mm - r.start).dot(r.axis);
    const double pressing = t >= t_push ? k_n_per_mm * std::max(0.0, d) : 0.0;
    FeedbackFrame fb;
    fb.force_n[0] = -pressing * r.axis;
    s->Feedback(fb);
    r.t.push_back(t);
    r.depth_mm.push_back(d);
    r.pressing_n.push_back(pressing);
    r.frames.push_back(f);
  }
  return r;
}

std::size_t IndexAt(const SpringRun& /*r*/, double t) {
  return static_cast<std::size_t>(std::llround(t / kDt)) - 1;
}

TEST(ForcePush, SettlesAtForceOverStiffnessAlongTheDiscreteExponential) {
  const Model m = MakeTestModel();
  ScriptSource s(Script("{force: 1.0, duration: 3.0}", "  - wait: 0.5\n"), "t.yaml", m, Opt());
  const double k = 0.5, F = 1.0, gain = 5.0;  // default gain, mm/(s N)
  const SpringRun r = RunSpring(&s, k, 4.5);
  // Explicit update d_n = d_{n-1} + dt g (F - k d_{n-1}): d_n = F/k (1 - (1 - g k dt)^n).
  const double c = gain * k * kDt;
  // (The push ends at t = 4 s, step n = 300; its last integration is n = 299.)
  for (int n : {0, 1, 2, 25, 50, 100, 200, 299}) {
    const double expect = F / k * (1.0 - std::pow(1.0 - c, n));
    EXPECT_NEAR(r.depth_mm[IndexAt(r, 1.0 + n * kDt)], expect, 1e-9) << "n = " << n;
  }
  // Settled within 0.01 mm of F/k = 2 mm after 3 s (7.5 time constants of 0.4 s).
  EXPECT_NEAR(r.depth_mm[IndexAt(r, 3.99)], F / k, 0.01);
  EXPECT_NEAR(r.pressing_n[IndexAt(r, 3.99)], F, 0.005);
  // The position never leaves the axis of the push.
  const Vec3 p = r.frames[IndexAt(r, 3.99)].tools[0].pose.position_mm;
  EXPECT_NEAR(((p - r.start) - r.depth_mm[IndexAt(r, 3.99)] * r.axis).norm(), 0.0, 1e-12);
  // A wait after the push holds the reached depth.
  EXPECT_EQ(r.depth_mm[IndexAt(r, 4.4)], r.depth_mm[IndexAt(r, 3.99)]);
}

TEST(ForcePush, FollowsARampWithTheFirstOrderLag) {
  const Model m = MakeTestModel();
  // 0 -> 2 N in 2 s (1 N/s), then 2 N held for 2 s.
  ScriptSource s(Script("{force: [[0, 0], [2, 2], [4, 2]]}"), "t.yaml", m, Opt());
  const double k = 0.5, gain = 5.0, rate = 1.0;
  const SpringRun r = RunSpring(&s, k, 5.0);
  // Steady ramp tracking of d' = g (F - k d): the force lags by rate / (g k) = 0.4 N.
  const double lag = rate / (gain * k);
  EXPECT_NEAR(r.pressing_n[IndexAt(r, 3.0)], 2.0 - lag, 0.02);
  EXPECT_NEAR(r.pressing_n[IndexAt(r, 2.5)], 1.5 - lag, 0.03);
  for (double t = 1.05; t < 3.0; t += 0.1) {
    EXPECT_LT(r.pressing_n[IndexAt(r, t)], r.pressing_n[IndexAt(r, t + 0.05)]) << t;
  }
  // After 2 s of hold (5 time constants) the force reaches the target.
  EXPECT_NEAR(r.pressing_n[IndexAt(r, 4.99)], 2.0, 0.01);
}

TEST(ForcePush, SpeedAndDepthLimitsInFreeSpaceAndRampStartsAtZero) {
  const Model m = MakeTestModel();
  // No contact: the rate g F = 25 mm/s is clamped to 10 mm/s, the travel to 3 mm.
  ScriptSource s(Script("{force: 5, max_depth: 3, duration: 1}"), "t.yaml", m, Opt());
  const SpringRun r = RunSpring(&s, 0.0, 2.0);
  EXPECT_NEAR(r.depth_mm[IndexAt(r, 1.2)], 2.0, 1e-9);
  EXPECT_NEAR(r.depth_mm[IndexAt(r, 1.99)], 3.0, 1e-12);
  // `ramp`: the target rises linearly from 0, so the first steps move at g F(t).
  ScriptSource q(Script("{force: 1, ramp: 1, gain: 2, duration: 1.5}"), "t.yaml", m, Opt());
  const SpringRun rq = RunSpring(&q, 0.0, 1.5);
  // depth(1 + n dt) = sum_{i=1..n} 2 * (i dt) * dt.
  const int n = 20;
  EXPECT_NEAR(rq.depth_mm[IndexAt(rq, 1.0 + n * kDt)], 2.0 * kDt * kDt * n * (n + 1) / 2, 1e-9);
}

TEST(ForcePush, ExcursionIsBlendedOutByTheNextMove) {
  const Model m = MakeTestModel();
  ScriptSource s(Script("{force: 1.0, duration: 1.0}",
                        "  - close: {duration: 0.2}\n"
                        "  - push: {depth: -2, duration: 0.5, easing: linear}\n"),
                 "t.yaml", m, Opt());
  const SpringRun r = RunSpring(&s, 1.0, 3.0);
  const double reached = r.depth_mm[IndexAt(r, 1.99)];
  EXPECT_GT(reached, 0.9);
  EXPECT_EQ(r.depth_mm[IndexAt(r, 2.1)], reached);  // jaw closes at the pushed depth
  // Halfway through the depth push: half the excursion and half of -2 mm.
  EXPECT_NEAR(r.depth_mm[IndexAt(r, 2.45)], 0.5 * reached - 1.0, 1e-9);
  // At its end the written position holds again: the push's start minus 2 mm.
  EXPECT_NEAR(r.depth_mm[IndexAt(r, 2.7)], -2.0, 1e-9);
}

TEST(ForcePush, ASecondForcePushStartsWhereTheFirstLeftAndTheCameraFollowsTheTip) {
  const Model m = MakeTestModel();
  const std::string y = Script("{force: 1.0, duration: 1.0}",
                               "  - press: {button: 1, duration: 0.1}\n"
                               "  - push: {force: 0.5, duration: 1.0}\n") +
                        "camera:\n  - follow: {target: slot0, duration: 4, transition: 0.1}\n";
  ScriptSource s(y, "t.yaml", m, Opt());
  const SpringRun r = RunSpring(&s, 1.0, 3.1);
  // First push: 1 N on 1 N/mm, 5 time constants of 0.2 s -> within 1% of 1 mm.
  const double first = r.depth_mm[IndexAt(r, 1.99)];
  EXPECT_NEAR(first, 1.0, 0.01);
  // The second starts from there (no jump back to the written position) and relaxes to 0.5 mm.
  EXPECT_NEAR(r.depth_mm[IndexAt(r, 2.11)], first + 5.0 * kDt * (0.5 - first), 1e-9);
  EXPECT_NEAR(r.depth_mm[IndexAt(r, 3.09)], 0.5, 0.01);
  // The camera keeps the pushed tip on its line of sight (the oblique view, AimScopeView).
  const InputFrame& f = r.frames[IndexAt(r, 3.09)];
  const Vec3 to_tip = (f.tools[0].pose.position_mm - f.camera.pose.position_mm).normalized();
  const Vec3 view = f.camera.pose.orientation *
                    ScopeViewDirectionLocal(m.camera.lens_angle_deg * units::kDegToRad);
  EXPECT_NEAR(view.dot(to_tip), 1.0, 1e-9);
}

TEST(ForcePush, SameFeedbackGivesBitIdenticalFramesAndRepeatedTimesAreIdempotent) {
  const Model m = MakeTestModel();
  const std::string y = Script("{force: [[0, 0], [0.5, 1.5], [1.5, 0.5]], gain: 8}",
                               "  - withdraw: {duration: 0.5}\n");
  ScriptSource a(y, "t.yaml", m, Opt()), b(y, "t.yaml", m, Opt()), c(y, "t.yaml", m, Opt());
  const SpringRun ra = RunSpring(&a, 0.8, 3.2), rb = RunSpring(&b, 0.8, 3.2);
  const SpringRun rc = RunSpring(&c, 1.6, 3.2);  // another tissue
  ASSERT_EQ(ra.frames.size(), rb.frames.size());
  bool differs = false;
  for (std::size_t i = 0; i < ra.frames.size(); ++i) {
    EXPECT_TRUE(BitwiseEqual(ra.frames[i], rb.frames[i])) << "step " << i + 1;
    differs = differs || !BitwiseEqual(ra.frames[i], rc.frames[i]);
  }
  EXPECT_TRUE(differs);
  // Asking again for the same time does not integrate twice.
  ScriptSource d(y, "t.yaml", m, Opt());
  InputFrame f1, f2;
  FeedbackFrame fb;
  d.Frame(100, 1.0, &f1);
  d.Frame(110, 1.1, &f1);
  d.Feedback(fb);
  d.Frame(110, 1.1, &f2);
  EXPECT_TRUE(BitwiseEqual(f1, f2));
}

TEST(ForcePush, ValidationNamesFileLineAndField) {
  struct Case {
    std::string push, expect;
  };
  const std::vector<Case> cases = {
      {"{force: 1, speed: 3}", "t.yaml:4: field 'slot0[1].push.speed': unknown key 'speed'"},
      {"{force: 1, easing: linear}", "field 'slot0[1].push.easing': unknown key 'easing'"},
      {"{force: [[0, 0], [1, 1], [1, 2]]}",
       "t.yaml:4: field 'slot0[1].push.force[2]': keyframe times must increase (1 s after 1 s)"},
      {"{force: [[0, 0], [1, -1]]}",
       "field 'slot0[1].push.force[1]': force must be >= 0 N, found -1"},
      {"{force: -0.5}", "field 'slot0[1].push.force': force must be >= 0 N, found -0.5"},
      {"{force: [[-1, 0]]}", "field 'slot0[1].push.force[0]': keyframe time must be >= 0 s"},
      {"{force: [[0, 1, 2]]}", "field 'slot0[1].push.force[0]': expected [t, N]"},
      {"{force: []}", "field 'slot0[1].push.force': expected a number or a list"},
      {"{force: abc}", "field 'slot0[1].push.force': expected a number, found 'abc'"},
      {"{force: 1, depth: 2}", "field 'slot0[1].push.depth': give either depth or force"},
      {"{force: [[0, 0], [1, 1]], ramp: 0.5}", "field 'slot0[1].push.ramp': ramp needs a"},
      {"{force: 1, ramp: 2, duration: 1}", "field 'slot0[1].push.ramp': longer than the duration"},
      {"{force: [[0, 0], [2, 1]], duration: 1}",
       "field 'slot0[1].push.duration': shorter than the last keyframe (2 s)"},
      {"{force: 1, gain: 0}", "field 'slot0[1].push.gain': must be > 0"},
      {"{force: 1, max_speed: -1}", "field 'slot0[1].push.max_speed': must be > 0"},
      {"{forse: 1}", "field 'slot0[1].push.forse': unknown key 'forse'; allowed: depth, force"},
  };
  for (const Case& c : cases) {
    const std::string e = testing::ScriptErrorOf(Script(c.push));
    EXPECT_NE(e.find(c.expect), std::string::npos) << "got: " << e << "\nexpected: " << c.expect;
  }
  EXPECT_EQ(testing::ScriptErrorOf(Script("{force: [[0, 0], [0.5, 1]], max_depth: 4}")), "");
}

}  // namespace
}  // namespace arthrosim::input
