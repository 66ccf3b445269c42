#include "arthrosim/input/recorded_source.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "arthrosim/core/error.h"
#include "arthrosim/input/pose_math.h"

namespace arthrosim::input {

std::int64_t LatchBucket(double t_s, double dt_s) {
  // Tolerance so that a sample written at exactly k*dt (as printed by the recorder) lands in
  // step k, not k+1, despite rounding in t/dt.
  return static_cast<std::int64_t>(std::ceil(t_s / dt_s - 1e-9));
}

RecordedSource::RecordedSource(const SessionTable& table, const Model& model, double dt_s,
                               const SessionOptions& options)
    : camera_initial_(model.camera.initial_pose), dt_s_(dt_s), warnings_(table.warnings) {
  if (!(dt_s > 0.0)) throw InputError(table.file, 0, "dt", "simulation step must be > 0");
  bool first = true;
  for (const SessionRow& r : table.rows) {
    Sample s;
    s.t_s = r.t_s;
    s.bucket = LatchBucket(r.t_s, dt_s);
    if (!r.instrument.empty()) {
      s.instrument = model.FindInstrument(r.instrument);
      if (s.instrument < 0) {
        std::string names;
        for (const InstrumentModel& im : model.instruments)
          names += (names.empty() ? "" : ", ") + im.name;
        throw InputError(table.file, r.line, "instrument",
                         fmt::format("unknown instrument '{}'; the scenario has: {}", r.instrument,
                                     names.empty() ? "(none)" : names));
      }
    }
    s.pose.position_mm = r.position_mm;
    s.pose.orientation = r.orientation;
    s.jaw = r.jaw;
    s.buttons = r.buttons;
    s.lens_roll_rad = r.lens_roll_rad;
    s.head_roll_rad = r.head_roll_rad;
    auto& v = samples_[static_cast<int>(r.device)];
    if (!v.empty() && r.t_s < v.back().t_s) {
      throw InputError(table.file, r.line, "t", "timestamps of a device must not decrease");
    }
    if (!v.empty() && options.max_gap_s > 0 && r.t_s - v.back().t_s > options.max_gap_s) {
      if (options.gap_policy == GapPolicy::kError) {
        throw InputError(table.file, r.line, "t",
                         fmt::format("gap exceeds {} s", options.max_gap_s));
      }
      v.back().hold_after = true;
    }
    v.push_back(s);
    end_time_s_ = first ? r.t_s : std::max(end_time_s_, r.t_s);
    first = false;
  }
}

std::unique_ptr<RecordedSource> RecordedSource::Open(const std::string& path, const Model& model,
                                                     double dt_s, const SessionOptions& options) {
  return std::make_unique<RecordedSource>(ReadSession(path, options), model, dt_s, options);
}

bool RecordedSource::Evaluate(int d, double t_s, std::int64_t bucket, Sample* out) const {
  const auto& v = samples_[d];
  // Last sample with t <= t_s (the later of equal timestamps wins).
  auto it = std::upper_bound(v.begin(), v.end(), t_s,
                             [](double t, const Sample& s) { return t < s.t_s; });
  if (it == v.begin()) return false;
  const std::size_t i = static_cast<std::size_t>(it - v.begin()) - 1;
  const Sample& a = v[i];
  *out = a;
  if (i + 1 < v.size() && a.t_s != t_s && !a.hold_after && v[i + 1].instrument == a.instrument) {
    const Sample& b = v[i + 1];
    const double u = (t_s - a.t_s) / (b.t_s - a.t_s);
    out->pose.position_mm = Lerp(a.pose.position_mm, b.pose.position_mm, u);
    out->pose.orientation = Slerp(a.pose.orientation, b.pose.orientation, u);
    out->jaw = Lerp(a.jaw, b.jaw, u);
    out->lens_roll_rad = Lerp(a.lens_roll_rad, b.lens_roll_rad, u);
    out->head_roll_rad = Lerp(a.head_roll_rad, b.head_roll_rad, u);
  }
  // Latch: any press among the samples of this step's interval counts, however short.
  auto lo = std::lower_bound(v.begin(), v.end(), bucket,
                             [](const Sample& s, std::int64_t k) { return s.bucket < k; });
  for (auto p = lo; p != v.end() && p->bucket == bucket; ++p) out->buttons |= p->buttons;
  return true;
}

void RecordedSource::Frame(std::int64_t /*step*/, double t_s, InputFrame* out) {
  const std::int64_t bucket = static_cast<std::int64_t>(std::llround(t_s / dt_s_));
  for (int s = 0; s < kToolSlots; ++s) {
    Sample smp;
    ToolCommand& tc = out->tools[s];
    if (!Evaluate(s, t_s, bucket, &smp)) {
      tc = ToolCommand{};
      continue;
    }
    tc.instrument = smp.instrument;
    tc.pose = smp.pose;
    tc.jaw = smp.jaw;
    tc.buttons = smp.buttons;
  }
  Sample cam;
  if (Evaluate(static_cast<int>(Device::kScope), t_s, bucket, &cam)) {
    out->camera.pose = cam.pose;
    out->camera.lens_roll_rad = cam.lens_roll_rad;
    out->camera.head_roll_rad = cam.head_roll_rad;
  } else {
    out->camera = CameraCommand{};
    out->camera.pose = camera_initial_;
  }
}

}  // namespace arthrosim::input
