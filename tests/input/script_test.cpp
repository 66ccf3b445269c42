// Synthetic scripts: easing, landmarks, aiming, buttons, camera, validation, noise, the tour.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <map>
#include <string>

#include "arthrosim/core/error.h"
#include "arthrosim/core/scope_aim.h"
#include "arthrosim/core/units.h"
#include "arthrosim/input/pose_math.h"
#include "arthrosim/input/script_source.h"
#include "test_model.h"

namespace arthrosim::input {
namespace {

using testing::MakeTestModel;

ScriptOptions Opt(double dt = 0.01) {
  ScriptOptions o;
  o.dt_s = dt;
  return o;
}

InputFrame At(ScriptSource& s, double t) {
  InputFrame f;
  s.Frame(static_cast<std::int64_t>(std::llround(t / 0.01)), t, &f);
  return f;
}

TEST(Easing, EndpointsValuesAndFlatEnds) {
  for (Easing e : {Easing::kLinear, Easing::kSmoothstep, Easing::kMinimumJerk}) {
    EXPECT_EQ(Ease(e, 0.0), 0.0);
    EXPECT_EQ(Ease(e, 1.0), 1.0);
    EXPECT_NEAR(Ease(e, 0.5), 0.5, 1e-15);
  }
  EXPECT_DOUBLE_EQ(Ease(Easing::kSmoothstep, 0.25), 0.15625);
  EXPECT_DOUBLE_EQ(Ease(Easing::kMinimumJerk, 0.25), 0.103515625);
  const double h = 1e-6;
  // Minimum jerk: zero velocity and acceleration at the ends; smoothstep: zero velocity only.
  EXPECT_NEAR(Ease(Easing::kMinimumJerk, h) / h, 0.0, 1e-9);
  EXPECT_NEAR((Ease(Easing::kMinimumJerk, 2 * h) - 2 * Ease(Easing::kMinimumJerk, h)) / (h * h),
              0.0, 1e-4);
  EXPECT_NEAR(Ease(Easing::kSmoothstep, h) / h, 0.0, 1e-5);
  EXPECT_NEAR((Ease(Easing::kSmoothstep, 2 * h) - 2 * Ease(Easing::kSmoothstep, h)) / (h * h), 6.0,
              1e-3);
}

const char* kBasic = R"(name: basic
slot0:
  - pick: {instrument: grasper, toward: tear_edge_center, depth: 10, duration: 1.0, easing: linear}
  - move: {to: tear_edge_center, offset: [0, 0, 2], duration: 2.0, easing: linear}
  - close: {duration: 0.5, easing: linear}
  - press: {button: 2, duration: 0.004, at: 3.513}
  - hold: {button: 1}
  - wait: 0.2
  - release: {button: 1}
  - withdraw: {duration: 1.0}
)";

TEST(Script, PickEntersThroughThePortalAndMoveReachesLandmarkPlusOffset) {
  const Model m = MakeTestModel();
  ScriptSource s(kBasic, "t.yaml", m, Opt());
  const Vec3 portal = m.portals[m.FindPortal("anterior")].position_mm;
  const Vec3 target = m.landmarks[m.FindLandmark("tear_edge_center")].position_mm;
  const Vec3 dir = (target - portal).normalized();
  InputFrame f = At(s, 0.0);
  EXPECT_EQ(f.tools[0].instrument, m.FindInstrument("grasper"));
  EXPECT_NEAR((f.tools[0].pose.position_mm - portal).norm(), 0.0, 1e-12);
  f = At(s, 0.5);
  EXPECT_NEAR((f.tools[0].pose.position_mm - (portal + 5.0 * dir)).norm(), 0.0, 1e-12);
  // The instrument axis (+z) points from the portal to the tip.
  EXPECT_NEAR(((f.tools[0].pose.orientation * Vec3::UnitZ()) - dir).norm(), 0.0, 1e-12);
  const Vec3 start = portal + 10.0 * dir;
  const Vec3 end = target + Vec3(0, 0, 2);
  f = At(s, 1.5);  // a quarter of the linear move
  EXPECT_NEAR((f.tools[0].pose.position_mm - (start + 0.25 * (end - start))).norm(), 0.0, 1e-12);
  EXPECT_NEAR(((f.tools[0].pose.orientation * Vec3::UnitZ()) -
               (f.tools[0].pose.position_mm - portal).normalized())
                  .norm(),
              0.0, 1e-12);
  f = At(s, 3.0);
  EXPECT_NEAR((f.tools[0].pose.position_mm - end).norm(), 0.0, 1e-12);
  EXPECT_EQ(f.tools[0].jaw, 0.0);
  EXPECT_NEAR(At(s, 3.25).tools[0].jaw, 0.5, 1e-12);
  EXPECT_EQ(At(s, 3.5).tools[0].jaw, 1.0);
}

TEST(Script, ButtonsLatchShortPressesAndHoldUntilRelease) {
  ScriptSource s(kBasic, "t.yaml", MakeTestModel(), Opt());
  // press of button 2 during [3.513, 3.517): between steps 3.51 and 3.52, latched into 3.52.
  EXPECT_EQ(At(s, 3.51).tools[0].buttons, 0);
  EXPECT_EQ(At(s, 3.52).tools[0].buttons & 2, 2);
  EXPECT_EQ(At(s, 3.53).tools[0].buttons & 2, 0);
  // hold at 3.517, release at 3.717.
  EXPECT_EQ(At(s, 3.60).tools[0].buttons, 1);
  EXPECT_EQ(At(s, 3.72).tools[0].buttons, 1);  // released within (3.71, 3.72]: still seen
  EXPECT_EQ(At(s, 3.73).tools[0].buttons, 0);
  // withdraw ends at 4.717: instrument gone, tip back at the portal.
  const Model m = MakeTestModel();
  const InputFrame f = At(s, 4.72);
  EXPECT_EQ(f.tools[0].instrument, -1);
  EXPECT_NEAR(
      (f.tools[0].pose.position_mm - m.portals[m.FindPortal("anterior")].position_mm).norm(), 0,
      1e-12);
  EXPECT_FALSE(s.Finished(4.71));
  EXPECT_TRUE(s.Finished(4.72));
}

TEST(Script, AimDirectionStandoffAndPush) {
  const Model m = MakeTestModel();
  const std::string y = R"(name: aim
slot1:
  - pick: {instrument: burr, depth: 5, duration: 0.5}
  - move: {to: spur_tip, standoff: 3, duration: 1.0}
  - push: {depth: 3, duration: 0.5}
  - move: {to: spur_tip, aim: [0, 0, -1], duration: 1.0}
)";
  ScriptSource s(y, "t.yaml", m, Opt());
  const Vec3 portal = m.portals[m.FindPortal("lateral")].position_mm;
  const Vec3 spur = m.landmarks[m.FindLandmark("spur_tip")].position_mm;
  const Vec3 dir = (spur - portal).normalized();
  EXPECT_NEAR((At(s, 1.5).tools[1].pose.position_mm - (spur - 3 * dir)).norm(), 0, 1e-12);
  EXPECT_NEAR((At(s, 2.0).tools[1].pose.position_mm - spur).norm(), 0, 1e-12);  // touched
  const InputFrame f = At(s, 3.0);
  EXPECT_NEAR(((f.tools[1].pose.orientation * Vec3::UnitZ()) - Vec3(0, 0, -1)).norm(), 0, 1e-12);
  // Mid-way the orientation is a slerp: the axis turns monotonically toward -z.
  const double c1 = (At(s, 2.3).tools[1].pose.orientation * Vec3::UnitZ()).dot(Vec3(0, 0, -1));
  const double c2 = (At(s, 2.6).tools[1].pose.orientation * Vec3::UnitZ()).dot(Vec3(0, 0, -1));
  EXPECT_LT(c1, c2);
}

TEST(Script, CameraMovesLooksAndFollowsAHand) {
  const Model m = MakeTestModel();
  const std::string y = R"(name: cam
camera:
  - move: {position: subacromial_center, offset: [-20, 0, 0], look_at: subacromial_center, lens_roll: 30, head_roll: -10, duration: 1.0}
  - follow: {target: slot0, duration: 2.0, transition: 0.5}
slot0:
  - pick: {instrument: shaver, depth: 10, duration: 1.0, at: 1.0}
  - move: {to: footprint_center, duration: 1.0}
)";
  ScriptSource s(y, "t.yaml", m, Opt());
  InputFrame f = At(s, 1.0);
  const Vec3 sc = m.landmarks[m.FindLandmark("subacromial_center")].position_mm;
  EXPECT_NEAR((f.camera.pose.position_mm - (sc + Vec3(-20, 0, 0))).norm(), 0, 1e-12);
  // the oblique view at zero lens roll (not the shaft) looks at the target; lens_roll then
  // sweeps it about the shaft
  const Vec3 view_local = ScopeViewDirectionLocal(m.camera.lens_angle_deg * units::kDegToRad);
  EXPECT_NEAR(((f.camera.pose.orientation * view_local) - Vec3(1, 0, 0)).norm(), 0, 1e-12);
  EXPECT_NEAR(f.camera.lens_roll_rad, 30 * units::kDegToRad, 1e-15);
  EXPECT_NEAR(f.camera.head_roll_rad, -10 * units::kDegToRad, 1e-15);
  for (double t : {1.6, 2.2, 2.9}) {
    f = At(s, t);
    const Vec3 view = f.camera.pose.orientation * view_local;
    const Vec3 to_tip = (f.tools[0].pose.position_mm - f.camera.pose.position_mm).normalized();
    EXPECT_NEAR((view - to_tip).norm(), 0, 1e-9) << t;
  }
  // Before any action the camera sits at the scenario's initial pose.
  ScriptSource idle("name: idle\n", "t.yaml", m, Opt());
  EXPECT_TRUE(At(idle, 0.0).camera.pose == m.camera.initial_pose);
}

// The first camera move starts from where the scope looked at its initial pose: its view turns
// from there toward the new look point, never round through the way behind it.
TEST(Script, TheFirstCameraMoveStartsFromTheInitialView) {
  const Model m = MakeTestModel();
  const std::string y = R"(name: first
camera:
  - move: {look_at: footprint_center, duration: 1.0}
)";
  ScriptSource s(y, "t.yaml", m, Opt());
  const Vec3 eye = m.camera.initial_pose.position_mm;
  const Vec3 view_local = ScopeViewDirectionLocal(m.camera.lens_angle_deg * units::kDegToRad);
  const Vec3 initial_view = m.camera.initial_pose.orientation * view_local;
  const Vec3 to_target =
      (m.landmarks[m.FindLandmark("footprint_center")].position_mm - eye).normalized();
  double last = -2;
  for (double t : {0.0, 0.02, 0.1, 0.3, 0.5, 0.7, 1.0}) {
    const InputFrame f = At(s, t);
    const Vec3 view = f.camera.pose.orientation * view_local;
    EXPECT_GT(view.dot(initial_view), initial_view.dot(to_target) - 1e-9) << t;  // in between
    EXPECT_GE(view.dot(to_target), last - 1e-12) << t;  // turns toward the target
    last = view.dot(to_target);
  }
  EXPECT_NEAR(last, 1.0, 1e-12);
}

TEST(ScriptValidation, ErrorsNameFileLineAndField) {
  struct Case {
    std::string yaml, expect;
  };
  const std::vector<Case> cases = {
      {"name: x\nslot0:\n  - pick: {instrument: grasper, speed: 3}\n",
       "t.yaml:3: field 'slot0[0].pick.speed': unknown key 'speed'"},
      {"name: x\nslot0:\n  - pick: {instrument: grasper}\n  - move: {to: nowhere}\n",
       "t.yaml:4: field 'slot0[1].move.to': unknown landmark 'nowhere'"},
      {"name: x\nslot0:\n  - pick: {instrument: laser, toward: spur_tip}\n",
       "t.yaml:3: field 'slot0[0].pick.instrument': unknown instrument 'laser'"},
      {"name: x\nslot0:\n  - pick: {instrument: grasper, portal: superior, toward: spur_tip}\n",
       "t.yaml:3: field 'slot0[0].pick.portal': unknown portal 'superior'"},
      {"name: x\nslot1:\n  - move: {to: spur_tip}\n",
       "t.yaml:3: field 'slot1[0].move': no instrument in slot1"},
      {"name: x\nslot0:\n  - pick: {instrument: hook, toward: spur_tip}\nslot1:\n  - pick: "
       "{instrument: hook, toward: spur_tip, at: 0.5}\n",
       "'hook' is in slot0 and slot1 at the same time"},
      {"name: x\nslot0:\n  - wait: 2\n  - pick: {instrument: hook, toward: spur_tip, at: 1}\n",
       "t.yaml:4: field 'slot0[1].pick.at': starts at 1 s, before the previous action ends at 2 s"},
      {"name: x\nslot0:\n  - pick: {instrument: hook, toward: spur_tip, easing: bouncy}\n",
       "field 'slot0[0].pick.easing': unknown easing 'bouncy'"},
      {"name: x\nslot0:\n  - jump: {}\n", "t.yaml:3: field 'slot0[0]': unknown action 'jump'"},
      {"name: x\ncamera:\n  - move: {look_at: slot2}\n",
       "t.yaml:3: field 'camera[0].move.look_at': unknown landmark 'slot2'"},
      {"name: x\nspeed: 2\n", "t.yaml:2: field 'speed': unknown key 'speed'"},
      {"name: x\nslot0: [\n", "t.yaml:3: YAML syntax"},
      {"name: x\nnoise: {tremor_amplitude: -1}\n", "field 'noise.tremor_amplitude': must be >= 0"},
      {"name: x\nslot0:\n  - pick: {instrument: hook, toward: spur_tip, duration: abc}\n",
       "field 'slot0[0].pick.duration': expected a number, found 'abc'"},
  };
  for (const Case& c : cases) {
    const std::string e = testing::ScriptErrorOf(c.yaml);
    EXPECT_NE(e.find(c.expect), std::string::npos) << "got: " << e << "\nexpected: " << c.expect;
  }
}

const char* kNoisy = R"(name: noisy
noise: {tremor_amplitude: 0.5, tremor_frequency: 8, overshoot: 0.2, hesitation_probability: 0.5, hesitation_min: 0.1, hesitation_max: 0.4}
slot0:
  - pick: {instrument: grasper, depth: 10, duration: 0.5}
  - move: {to: tear_edge_center, duration: 1.0}
  - close: {duration: 0.3}
  - move: {to: footprint_center, duration: 1.0}
  - withdraw: {duration: 0.5}
)";

std::vector<InputFrame> RunScript(const std::string& yaml, const ScriptOptions& o, int steps) {
  ScriptSource s(yaml, "t.yaml", MakeTestModel(), o);
  std::vector<InputFrame> out(steps);
  for (int k = 0; k < steps; ++k) s.Frame(k, k * o.dt_s, &out[k]);
  return out;
}

TEST(ScriptNoise, SameSeedSameFramesDifferentSeedDifferentFrames) {
  ScriptOptions a = Opt();
  a.seed = 42;
  a.noise_scale = 1;
  const auto r1 = RunScript(kNoisy, a, 400);
  const auto r2 = RunScript(kNoisy, a, 400);
  for (int k = 0; k < 400; ++k) ASSERT_TRUE(BitwiseEqual(r1[k], r2[k])) << k;
  ScriptOptions b = a;
  b.seed = 43;
  const auto r3 = RunScript(kNoisy, b, 400);
  int differ = 0;
  for (int k = 0; k < 400; ++k) differ += BitwiseEqual(r1[k], r3[k]) ? 0 : 1;
  EXPECT_GT(differ, 300);
  // Hesitations and overshoot change the run's length and path, not just the tremor.
  ScriptSource s1(kNoisy, "t.yaml", MakeTestModel(), a), s3(kNoisy, "t.yaml", MakeTestModel(), b);
  ScriptOptions expert = Opt();
  expert.noise_scale = 0;
  ScriptSource e(kNoisy, "t.yaml", MakeTestModel(), expert);
  EXPECT_DOUBLE_EQ(e.end_time_s(), 3.3);
  EXPECT_GE(s1.end_time_s(), 3.3);
  EXPECT_NE(s1.end_time_s(), s3.end_time_s());
}

TEST(ScriptNoise, TremorIsBoundedByItsAmplitudeAndScaleZeroIsTheExpert) {
  ScriptOptions tremor_only = Opt();
  tremor_only.seed = 5;
  tremor_only.noise_scale = 1;
  NoiseParams p;
  p.tremor_amplitude_mm = 0.5;
  tremor_only.noise = p;
  ScriptOptions expert = tremor_only;
  expert.noise_scale = 0;
  const auto t = RunScript(kNoisy, tremor_only, 300);
  const auto e = RunScript(kNoisy, expert, 300);
  double max_dev = 0;
  for (int k = 0; k < 300; ++k) {
    const Vec3 d = t[k].tools[0].pose.position_mm - e[k].tools[0].pose.position_mm;
    max_dev = std::max(max_dev, d.cwiseAbs().maxCoeff());
  }
  EXPECT_LE(max_dev, 0.5 + 1e-12);
  EXPECT_GT(max_dev, 0.2);  // it does shake
  const auto plain = RunScript(
      std::string(kNoisy).substr(std::string(kNoisy).find("slot0:")).insert(0, "name: plain\n"),
      Opt(), 300);
  const auto by_default = RunScript(kNoisy, Opt(), 300);  // noise block present, scale 0
  for (int k = 0; k < 300; ++k) ASSERT_TRUE(BitwiseEqual(by_default[k], plain[k])) << k;
  for (int k = 0; k < 300; ++k) ASSERT_TRUE(BitwiseEqual(e[k], plain[k])) << k;
}

// Landmark each instrument of the tour must touch.
const std::map<std::string, std::string> kTourTargets = {{"burr", "spur_tip"},
                                                         {"shaver", "footprint_center"},
                                                         {"awl", "anchor_site_1"},
                                                         {"scorpion_needle", "bite_target_1"},
                                                         {"knot_pusher", "anchor_site_2"},
                                                         {"scissors", "biceps_cut_site"},
                                                         {"electrocautery", "subacromial_center"},
                                                         {"grasper", "tear_edge_center"},
                                                         {"retriever", "bite_target_2"},
                                                         {"cutter", "anchor_site_2"},
                                                         {"hook", "muscle_belly"}};

void CheckTour(const Model& m) {
  const std::string path =
      std::string(ARTHROSIM_SOURCE_DIR) + "/trajectories/rotator_cuff_tour.yaml";
  ScriptOptions o = Opt(0.01);
  auto s = ScriptSource::Open(path, m, o);
  ASSERT_LE(s->end_time_s(), 60.0);
  std::map<std::string, double> closest;
  Vec3 cam0 = Vec3::Zero();
  double cam_travel = 0;
  const int steps = static_cast<int>(s->end_time_s() / 0.01) + 2;
  for (int k = 0; k < steps; ++k) {
    InputFrame f;
    s->Frame(k, k * 0.01, &f);
    for (const ToolCommand& tc : f.tools) {
      ASSERT_TRUE(tc.pose.position_mm.allFinite());
      ASSERT_NEAR(tc.pose.orientation.norm(), 1.0, 1e-12);
      if (tc.instrument < 0) continue;
      const std::string& name = m.instruments[tc.instrument].name;
      const Vec3 target = m.landmarks[m.FindLandmark(kTourTargets.at(name))].position_mm;
      const double d = (tc.pose.position_mm - target).norm();
      closest[name] = closest.count(name) ? std::min(closest[name], d) : d;
    }
    if (k > 0) cam_travel += (f.camera.pose.position_mm - cam0).norm();
    cam0 = f.camera.pose.position_mm;
  }
  EXPECT_EQ(closest.size(), 11u);
  for (const auto& [name, d] : closest) EXPECT_LT(d, 1e-9) << name << " never touched its target";
  EXPECT_GT(cam_travel, 10.0);
  EXPECT_TRUE(s->Finished(s->end_time_s() + 0.01));
  // A trainee variant of the tour also loads and differs.
  o.seed = 9;
  o.noise_scale = 1;
  auto trainee = ScriptSource::Open(path, m, o);
  InputFrame a, b;
  s->Frame(1000, 10.0, &a);
  trainee->Frame(1000, 10.0, &b);
  EXPECT_FALSE(BitwiseEqual(a, b));
}

TEST(Tour, EveryInstrumentTouchesItsTargetWithinSixtySeconds) { CheckTour(MakeTestModel()); }

TEST(Tour, ValidAgainstTheRealScenarioWhenPresent) {
  const std::string path =
      std::string(ARTHROSIM_SOURCE_DIR) + "/scenarios/rotator_cuff_repair.yaml";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "scenario not written yet";
  CheckTour(testing::LoadScenarioSubset(path));
}

}  // namespace
}  // namespace arthrosim::input
