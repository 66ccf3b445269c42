// The scripted and scenario arthroscope aims its 30-degree view, not its shaft: after a script's
// `look_at` move, during a `follow`, and at the scenario's initial pose, the aimed point lies on
// the view axis of the renderer's ScopeViewFrame (the image centre) on the shoulder scene.
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "arthrosim/input/script_source.h"
#include "arthrosim/io/scenario_loader.h"
#include "arthrosim/render/scene.h"

namespace arthrosim::render {
namespace {

constexpr double kDeg = 3.14159265358979323846 / 180;
// The aimed point may sit this far off the image centre (the 105-degree image's radius is 52.5).
constexpr double kMaxOffCentreDeg = 0.01;

std::string Source(const std::string& rel) { return std::string(ARTHROSIM_SOURCE_DIR) + "/" + rel; }

const Model& Shoulder() {
  static const Model model = io::LoadScenario(Source("scenarios/rotator_cuff_repair.yaml"));
  return model;
}

Vec3 LandmarkAt(const Model& m, const std::string& name) {
  const int l = m.FindLandmark(name);
  EXPECT_GE(l, 0) << name;
  return l >= 0 ? m.landmarks[l].position_mm : Vec3::Zero();
}

SceneScope ScopeAt(const Model& m, const Pose& pose, double lens_roll, double head_roll) {
  SceneScope s;
  s.pose = pose;
  s.lens_angle_rad = m.camera.lens_angle_deg * kDeg;
  s.lens_roll_rad = lens_roll;
  s.head_roll_rad = head_roll;
  return s;
}

// Angle (deg) between the scope's view axis and the ray from its eye to `point`.
double OffCentreDeg(const SceneScope& scope, const Vec3& point) {
  const ViewFrame v = ScopeViewFrame(scope);
  const Vec3 d = (point - v.eye).normalized();
  return std::atan2(d.cross(v.forward).norm(), d.dot(v.forward)) / kDeg;
}

// Angle (deg) between the shaft (+z) and the ray to `point`: the 30 degrees the old aim lost.
double OffShaftDeg(const Pose& pose, const Vec3& point) {
  const Vec3 d = (point - pose.position_mm).normalized();
  return std::acos(std::clamp((pose.orientation * Vec3::UnitZ()).dot(d), -1.0, 1.0)) / kDeg;
}

InputFrame FrameAt(input::ScriptSource& s, double t) {
  InputFrame f;
  s.Frame(std::llround(t / 0.02), t, &f);
  return f;
}

TEST(ScopeAimView, ALookAtMovePutsItsTargetInTheImageCentre) {
  const Model& m = Shoulder();
  ASSERT_EQ(m.camera.lens_angle_deg, 30);
  for (const char* target : {"spur_tip", "footprint_center", "tear_edge_center", "anchor_site_1"}) {
    const std::string y =
        std::string("name: look\ncamera:\n") +
        "  - move: {position: subacromial_center, standoff: 20, look_at: " + target +
        ", duration: 1.0}\n  - wait: 0.5\n";
    input::ScriptSource s(y, "look.yaml", m, input::ScriptOptions{});
    const Vec3 p = LandmarkAt(m, target);
    for (const double t : {1.0, 1.4}) {
      const InputFrame f = FrameAt(s, t);
      const SceneScope scope =
          ScopeAt(m, f.camera.pose, f.camera.lens_roll_rad, f.camera.head_roll_rad);
      EXPECT_LT(OffCentreDeg(scope, p), kMaxOffCentreDeg) << target << " t=" << t;
      EXPECT_NEAR(OffShaftDeg(f.camera.pose, p), 30, 1e-6) << target;  // an oblique view
    }
  }
}

TEST(ScopeAimView, AFollowKeepsTheWorkingTipInTheImageCentre) {
  const Model& m = Shoulder();
  const std::string y = R"(name: follow
camera:
  - move: {position: subacromial_center, standoff: 20, look_at: subacromial_center, duration: 1.0}
  - follow: {target: slot0, duration: 4.0, transition: 0.5}
slot0:
  - pick: {instrument: shaver, depth: 8, duration: 0.6, at: 1.0}
  - move: {to: footprint_center, standoff: 3, duration: 1.5}
  - move: {to: spur_tip, standoff: 3, duration: 1.5}
)";
  input::ScriptSource s(y, "follow.yaml", m, input::ScriptOptions{});
  int checked = 0;
  for (double t = 1.6; t <= 4.9; t += 0.3, ++checked) {
    const InputFrame f = FrameAt(s, t);
    ASSERT_GE(f.tools[0].instrument, 0) << t;
    const SceneScope scope =
        ScopeAt(m, f.camera.pose, f.camera.lens_roll_rad, f.camera.head_roll_rad);
    EXPECT_LT(OffCentreDeg(scope, f.tools[0].pose.position_mm), kMaxOffCentreDeg) << "t=" << t;
  }
  EXPECT_GE(checked, 10);
}

TEST(ScopeAimView, TheScenarioInitialPoseLooksAtItsLookAt) {
  const Model& m = Shoulder();
  const YAML::Node cam = YAML::LoadFile(Source("scenarios/rotator_cuff_repair.yaml"))["camera"];
  ASSERT_TRUE(cam["position"] && cam["look_at"]);
  const Vec3 eye(cam["position"][0].as<double>(), cam["position"][1].as<double>(),
                 cam["position"][2].as<double>());
  const Vec3 look(cam["look_at"][0].as<double>(), cam["look_at"][1].as<double>(),
                  cam["look_at"][2].as<double>());
  EXPECT_EQ(m.camera.initial_pose.position_mm, eye);
  EXPECT_LT(OffCentreDeg(ScopeAt(m, m.camera.initial_pose, 0, 0), look), kMaxOffCentreDeg);
  // and a script that never moves the camera starts from that view
  input::ScriptSource idle("name: idle\n", "idle.yaml", m, input::ScriptOptions{});
  EXPECT_LT(OffCentreDeg(ScopeAt(m, FrameAt(idle, 0).camera.pose, 0, 0), look), kMaxOffCentreDeg);
}

}  // namespace
}  // namespace arthrosim::render
