#include "arthrosim/scoring/run_data.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <numbers>

#include "arthrosim/core/error.h"
#include "arthrosim/io/run_reader.h"
#include "arthrosim/io/scenario_loader.h"
#include "arthrosim/render/scene.h"
#include "arthrosim/scoring/sight.h"

namespace arthrosim::scoring {
namespace {

render::SceneScope ScopeOf(const Model& model, const CameraState& camera) {
  render::SceneScope s;
  s.pose = camera.pose;
  s.lens_angle_rad = model.camera.lens_angle_deg * std::numbers::pi / 180.0;
  s.lens_roll_rad = camera.lens_roll_rad;
  s.head_roll_rad = camera.head_roll_rad;
  s.fov_rad = model.camera.fov_deg * std::numbers::pi / 180.0;
  s.near_mm = model.camera.near_mm;
  s.far_mm = model.camera.far_mm;
  return s;
}

void CheckMatches(const std::string& path, const io::RunInfo& info, const Model& model) {
  if (info.instruments.size() != model.instruments.size() ||
      info.bones.size() != model.bones.size() ||
      info.soft_bodies.size() != model.soft_bodies.size())
    throw InputError(path, 0, "/meta scenario_yaml",
                     "the run's bodies or instruments do not match its scenario");
  for (std::size_t i = 0; i < model.instruments.size(); ++i)
    if (info.instruments[i] != model.instruments[i].name)
      throw InputError(
          path, 0, "/tools/" + info.instruments[i],
          "instrument differs from the scenario's '" + model.instruments[i].name + "'");
}

// Which inserted instruments' tips and which landmarks the scope sees in this frame.
void AppendSight(const State& s, SightBlockers* blockers, RunData* d) {
  FrameSight sight(d->model, s, blockers);
  for (int slot = 0; slot < kToolSlots; ++slot) {
    const ToolState& t = s.tools[slot];
    if (t.instrument < 0 || t.instrument >= static_cast<int>(d->instruments.size())) continue;
    const double margin =
        d->model.instruments[static_cast<std::size_t>(t.instrument)].tip_radius_mm;
    d->instruments[t.instrument].tip_visible.back() = sight.Sees(t.pose.position_mm, margin);
  }
  for (std::size_t l = 0; l < d->landmark_visible.size(); ++l)
    d->landmark_visible[l].push_back(sight.SeesLandmark(static_cast<int>(l)));
}

void AppendFrame(const State& s, RunData* d) {
  d->time_s.push_back(s.time_s);
  d->step.push_back(s.step);
  for (InstrumentSeries& series : d->instruments) {
    series.active.push_back(0);
    series.pose.emplace_back();
    series.force_n.push_back(0.0);
    series.slot.push_back(-1);
    series.tip_visible.push_back(0);
  }
  for (int slot = 0; slot < kToolSlots; ++slot) {
    const ToolState& t = s.tools[slot];
    if (t.instrument < 0 || t.instrument >= static_cast<int>(d->instruments.size())) continue;
    InstrumentSeries& series = d->instruments[t.instrument];
    series.active.back() = 1;
    series.pose.back() = t.pose;
    series.force_n.back() = t.force_n.norm();
    series.slot.back() = static_cast<std::int8_t>(slot);
  }
  d->camera.push_back(s.camera);
  for (std::size_t b = 0; b < s.bones.size() && b < d->bone_removed_mm3.size(); ++b)
    d->bone_removed_mm3[b].push_back(s.bones[b].removed_volume_mm3);
  d->contacts.push_back(s.tool_contacts);
}

}  // namespace

std::int64_t RunData::FrameAt(double t) const {
  const auto it = std::lower_bound(time_s.begin(), time_s.end(), t - 1e-9);
  if (it == time_s.end()) return frames() - 1;
  return static_cast<std::int64_t>(it - time_s.begin());
}

Model LoadRunModel(const std::string& run_path, const std::string& scenario_override) {
  if (!scenario_override.empty()) return io::LoadScenario(scenario_override);
  io::RunReader reader(run_path);
  const io::RunInfo& info = reader.info();
  return io::LoadScenarioFromText(
      info.scenario_yaml,
      io::LocateRunScenario(run_path, info.scenario_path, info.scenario_path_absolute));
}

RunData ReadRunData(const std::string& run_path, Model model) {
  io::RunReader reader(run_path);
  CheckMatches(run_path, reader.info(), model);
  RunData d;
  d.path = run_path;
  d.model = std::move(model);
  for (const InstrumentModel& im : d.model.instruments)
    d.instruments.push_back({im.name, InstrumentKindName(im.kind), {}, {}, {}, {}, {}});
  d.bone_removed_mm3.resize(d.model.bones.size());
  d.landmark_visible.resize(d.model.landmarks.size());
  const std::int64_t frames = reader.frame_count();
  if (frames == 0) throw InputError(run_path, 0, "/time", "the run holds no frame");
  State s;
  SightBlockers blockers;
  for (std::int64_t k = 0; k < frames; ++k) {
    reader.ReadFrame(k, s);
    AppendFrame(s, &d);
    AppendSight(s, &blockers, &d);
  }
  d.last = std::move(s);
  d.events = reader.EventsUpTo(frames - 1);
  std::filesystem::path video(run_path);
  video.replace_extension(".mp4");
  d.video_beside = std::filesystem::exists(video);
  if (d.video_beside) d.video_path = video.filename().string();
  return d;
}

bool PointInView(const Model& model, const CameraState& camera, const Vec3& point_mm) {
  const render::SceneScope scope = ScopeOf(model, camera);
  const render::ViewFrame v = render::ScopeViewFrame(scope);
  const Vec3 d = point_mm - v.eye;
  const double along = d.dot(v.forward);
  if (!(along >= scope.near_mm && along <= scope.far_mm)) return false;
  const double angle = std::atan2(d.cross(v.forward).norm(), along);
  return angle <= 0.5 * scope.fov_rad;
}

double HorizonDeviationDeg(const Model& model, const CameraState& camera) {
  const render::ViewFrame v = render::ScopeViewFrame(ScopeOf(model, camera));
  Vec3 world_up = Vec3::UnitZ() - Vec3::UnitZ().dot(v.forward) * v.forward;
  if (world_up.norm() < 1e-9) return 0.0;
  world_up.normalize();
  const double c = std::clamp(world_up.dot(v.up), -1.0, 1.0);
  const double s = world_up.cross(v.up).norm();
  return std::atan2(s, c) * 180.0 / std::numbers::pi;
}

}  // namespace arthrosim::scoring
