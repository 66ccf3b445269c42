#include "test_model.h"

#include <yaml-cpp/yaml.h>

#include <filesystem>

#include "arthrosim/core/error.h"
#include "arthrosim/core/scope_aim.h"
#include "arthrosim/core/units.h"
#include "arthrosim/input/pose_math.h"
#include "arthrosim/input/script_source.h"

namespace arthrosim::input::testing {
namespace {

Vec3 ToVec(const YAML::Node& n) {
  return Vec3(n[0].as<double>(), n[1].as<double>(), n[2].as<double>());
}

}  // namespace

Model MakeTestModel() {
  Model m;
  m.name = "test_shoulder";
  m.scenario_path = "test_model";
  m.portals = {{"posterior", Vec3(-40, 0, 10)},
               {"anterior", Vec3(40, 0, 10)},
               {"lateral", Vec3(0, -40, 20)}};
  const char* portal_of[kInstrumentKindCount] = {"anterior", "lateral", "lateral",  "lateral",
                                                 "lateral",  "lateral", "anterior", "anterior",
                                                 "lateral",  "lateral", "anterior"};
  for (int k = 0; k < kInstrumentKindCount; ++k) {
    InstrumentModel im;
    im.kind = static_cast<InstrumentKind>(k);
    im.name = InstrumentKindName(im.kind);
    im.portal = portal_of[k];
    m.instruments.push_back(im);
  }
  m.landmarks = {{"footprint_center", "humerus", Vec3(5, -5, -5)},
                 {"anchor_site_1", "humerus", Vec3(2, -6, -6)},
                 {"anchor_site_2", "humerus", Vec3(8, -6, -6)},
                 {"spur_tip", "acromion", Vec3(0, -2, 12)},
                 {"tear_edge_center", "tendon", Vec3(4, 0, -2)},
                 {"bite_target_1", "tendon", Vec3(2, 1, -2)},
                 {"bite_target_2", "tendon", Vec3(7, 1, -2)},
                 {"biceps_cut_site", "biceps", Vec3(10, 8, -8)},
                 {"subacromial_center", "", Vec3(0, 0, 5)},
                 {"glenohumeral_view", "", Vec3(-5, 5, -10)},
                 {"muscle_belly", "muscle", Vec3(-20, 10, 0)}};
  m.camera.portal = "posterior";
  m.camera.initial_pose.position_mm = Vec3(-30, 0, 8);
  m.camera.initial_pose.orientation =
      AimScopeView(Vec3(-30, 0, 8), Vec3(0, 0, 5), m.camera.lens_angle_deg * units::kDegToRad);
  return m;
}

Model LoadScenarioSubset(const std::string& path) {
  const YAML::Node root = YAML::LoadFile(path);
  Model m;
  m.name = root["name"].as<std::string>();
  m.scenario_path = path;
  for (const YAML::Node& p : root["portals"]) {
    m.portals.push_back({p["name"].as<std::string>(), ToVec(p["position"])});
  }
  for (const YAML::Node& i : root["instruments"]) {
    InstrumentModel im;
    im.name = i["name"].as<std::string>();
    im.kind = *ParseInstrumentKind(i["kind"].as<std::string>());
    im.portal = i["portal"].as<std::string>();
    m.instruments.push_back(im);
  }
  for (const YAML::Node& l : root["landmarks"]) {
    m.landmarks.push_back({l["name"].as<std::string>(),
                           l["body"] ? l["body"].as<std::string>() : "", ToVec(l["position"])});
  }
  if (root["camera"] && root["camera"]["position"] && root["camera"]["look_at"]) {
    const Vec3 eye = ToVec(root["camera"]["position"]);
    m.camera.initial_pose.position_mm = eye;
    if (root["camera"]["lens_angle"])
      m.camera.lens_angle_deg = root["camera"]["lens_angle"].as<double>();
    m.camera.initial_pose.orientation = AimScopeView(eye, ToVec(root["camera"]["look_at"]),
                                                     m.camera.lens_angle_deg * units::kDegToRad);
  }
  return m;
}

std::string TempPath(const std::string& name) {
  const std::filesystem::path dir = std::filesystem::path(ARTHROSIM_BINARY_DIR) / "input_test_tmp";
  std::filesystem::create_directories(dir);
  return (dir / name).string();
}

std::string ScriptErrorOf(const std::string& yaml) {
  ScriptOptions options;
  options.dt_s = 0.01;
  try {
    ScriptSource s(yaml, "t.yaml", MakeTestModel(), options);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

}  // namespace arthrosim::input::testing
