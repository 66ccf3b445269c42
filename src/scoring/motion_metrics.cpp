// Motion metrics per instrument and for the camera, and what the camera showed: the share of
// working time a tip was seen (in the view cone and not hidden behind tissue or bone), the
// horizon deviation.
#include <fmt/core.h>

#include <cmath>
#include <limits>

#include "arthrosim/scoring/motion.h"
#include "score_internal.h"

namespace arthrosim::scoring::detail {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
// Economy fails above this ratio to the expert's path (arthroscopy and laparoscopy motion
// studies put novices at about 1.5-2.5x the expert path length).
constexpr double kMaxEconomyRatio = 2.0;

Track InstrumentTrack(const RunData& run, const InstrumentSeries& s) {
  Track track;
  bool open = false;
  for (std::int64_t k = 0; k < run.frames(); ++k) {
    if (!s.active[k]) {
      open = false;
      continue;
    }
    if (!open) track.emplace_back();
    open = true;
    track.back().t_s.push_back(run.time_s[k]);
    track.back().p_mm.push_back(s.pose[k].position_mm);
  }
  return track;
}

Track CameraTrack(const RunData& run) {
  Track track(1);
  for (std::int64_t k = 0; k < run.frames(); ++k) {
    track[0].t_s.push_back(run.time_s[k]);
    track[0].p_mm.push_back(run.camera[k].pose.position_mm);
  }
  return track;
}

double ReferencePath(const std::vector<const RunData*>& refs, const std::string& name,
                     bool camera) {
  if (refs.empty()) return kNaN;
  double sum = 0;
  for (const RunData* r : refs) {
    if (camera) {
      sum += PathLength(CameraTrack(*r));
      continue;
    }
    for (const InstrumentSeries& s : r->instruments)
      if (s.name == name) sum += PathLength(InstrumentTrack(*r, s));
  }
  return sum / static_cast<double>(refs.size());
}

void AddMotion(const Plan& plan, const std::string& who, const Track& track, double ref_path,
               ScoreReport* report) {
  const MotionThresholds& t = plan.motion;
  const MotionMetrics m = ComputeMotion(track, t.movement_speed_mm_s, t.idle_speed_mm_s);
  const std::string base = "motion." + who;
  AddMetric(report, base + ".path_length", "info", who + ": path length", "mm", m.path_length_mm,
            std::nullopt, std::nullopt);
  AddMetric(report, base + ".time", "info", who + ": time inserted", "s", m.time_s, std::nullopt,
            std::nullopt);
  AddMetric(report, base + ".movements", "info", who + ": number of movements", "count",
            m.movements, std::nullopt, std::nullopt);
  AddMetric(report, base + ".dimensionless_jerk", "info", who + ": dimensionless squared jerk", "",
            m.dimensionless_jerk, std::nullopt, std::nullopt);
  AddMetric(report, base + ".idle_time", "info", who + ": idle time", "s", m.idle_time_s,
            std::nullopt, std::nullopt);
  const double idle_share = m.time_s > 0 ? m.idle_time_s / m.time_s : kNaN;
  // The scope rests while the hands work: its idle share is information, not a fault.
  const bool banded = who != "camera" && m.time_s > 0;
  AddMetric(report, base + ".idle_share", banded ? "efficiency" : "info",
            who + ": idle share of inserted time", "", idle_share, std::nullopt,
            banded ? std::optional(t.max_idle_share) : std::nullopt);
  if (!std::isnan(ref_path) && ref_path > 0) {
    AddMetric(report, base + ".economy", "efficiency", who + ": path / expert path", "",
              m.path_length_mm / ref_path, std::nullopt, kMaxEconomyRatio);
  }
}

void CameraView(const Plan& plan, const RunData& run, ScoreReport* report) {
  double working = 0, in_view = 0, horizon_sum = 0, horizon_time = 0;
  for (std::int64_t k = 1; k < run.frames(); ++k) {
    const double dt = run.time_s[k] - run.time_s[k - 1];
    horizon_sum += HorizonDeviationDeg(run.model, run.camera[k]) * dt;
    horizon_time += dt;
    bool any = false, seen = false;
    for (const InstrumentSeries& s : run.instruments) {
      if (!s.active[k]) continue;
      any = true;
      seen = seen || s.tip_visible[k] != 0;
    }
    if (!any) continue;
    working += dt;
    if (seen) in_view += dt;
  }
  AddMetric(report, "camera.tip_in_view", "efficiency",
            "share of working time with an instrument tip seen by the scope (in view, not hidden)",
            "", working > 0 ? in_view / working : kNaN,
            working > 0 ? std::optional(plan.motion.min_tip_in_view) : std::nullopt, std::nullopt);
  AddMetric(report, "camera.horizon_deviation", "efficiency",
            "mean camera horizon deviation from anatomic up", "deg",
            horizon_time > 0 ? horizon_sum / horizon_time : kNaN, std::nullopt,
            plan.motion.max_horizon_deg);
}

}  // namespace

void EvaluateMotion(const Plan& plan, const RunData& run,
                    const std::vector<const RunData*>& references, ScoreReport* report) {
  for (const InstrumentSeries& s : run.instruments) {
    const Track track = InstrumentTrack(run, s);
    if (track.empty()) continue;
    AddMotion(plan, s.name, track, ReferencePath(references, s.name, false), report);
  }
  AddMotion(plan, "camera", CameraTrack(run), ReferencePath(references, "", true), report);
  CameraView(plan, run, report);
  AddMetric(report, "session.duration", "info", "session duration", "s", run.time_s.back(),
            std::nullopt, std::nullopt);
}

}  // namespace arthrosim::scoring::detail
