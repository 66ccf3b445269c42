#pragma once
// Replays a recorded session at the fixed simulation step (docs/trajectory-format.md):
// positions linear, orientations by shortest-arc slerp, jaw linear, buttons latched per step,
// instrument exchanges at the sample time. A pure function of the step time.
#include <array>
#include <memory>
#include <string>
#include <vector>

#include "arthrosim/input/input_source.h"
#include "arthrosim/input/session.h"

namespace arthrosim::input {

class RecordedSource : public InputSource {
 public:
  /// Resolves instrument names against `model` (InputError naming file/line otherwise).
  /// dt_s is the simulation step, s (> 0): it defines the button-latching interval.
  RecordedSource(const SessionTable& table, const Model& model, double dt_s,
                 const SessionOptions& options = {});
  /// Reads a .csv / .h5 session and builds the source.
  static std::unique_ptr<RecordedSource> Open(const std::string& path, const Model& model,
                                              double dt_s, const SessionOptions& options = {});

  void Frame(std::int64_t step, double t_s, InputFrame* out) override;
  /// True for t_s past the last sample of every device.
  bool Finished(double t_s) const override { return t_s > end_time_s_; }

  /// Time of the last sample, s.
  double end_time_s() const { return end_time_s_; }
  /// Repairs made while reading (truncated last line, normalised quaternions, held gaps).
  const std::vector<std::string>& warnings() const { return warnings_; }

 private:
  struct Sample {
    double t_s = 0;
    std::int64_t bucket = 0;  ///< step index k with (k-1) dt < t <= k dt
    std::int32_t instrument = -1;
    Pose pose;
    double jaw = 0;
    std::uint8_t buttons = 0;
    double lens_roll_rad = 0;
    double head_roll_rad = 0;
    bool hold_after = false;  ///< gap to the next sample exceeded the limit: no interpolation
  };
  /// Interpolated sample of device d at t_s (false before its first sample).
  bool Evaluate(int d, double t_s, std::int64_t bucket, Sample* out) const;

  std::array<std::vector<Sample>, kDeviceCount> samples_;
  Pose camera_initial_;
  double dt_s_ = 0;
  double end_time_s_ = 0;
  std::vector<std::string> warnings_;
};

/// The step index whose latching interval ((k-1) dt, k dt] holds time t_s (1e-9 dt tolerance).
std::int64_t LatchBucket(double t_s, double dt_s);

}  // namespace arthrosim::input
