#pragma once
// Synthetic scripts (trajectories/*.yaml, docs/trajectory-format.md): keyframed actions per hand
// and for the arthroscope, resolved against a Model's portals, instruments and landmarks. A
// seeded noise model (tremor, overshoot, hesitation) turns an expert script into trainee
// variants. Frames are a pure function of the step time and the seed, except during and after a
// force-profile push: that push advances the tool with an admittance law driven by the force fed
// back through Feedback, so frames then also depend on the (deterministic) feedback sequence.
#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "arthrosim/input/input_source.h"
#include "arthrosim/input/pose_math.h"

namespace arthrosim::input {

/// Trainee noise. All zero = the expert script as written.
struct NoiseParams {
  double tremor_amplitude_mm = 0;     ///< peak tremor displacement per axis, mm
  double tremor_frequency_hz = 8;     ///< centre frequency of physiological tremor, Hz
  double overshoot = 0;               ///< moves pass the target by this fraction of their length
  double hesitation_probability = 0;  ///< chance of a pause before each hand action, [0, 1]
  double hesitation_min_s = 0.2;      ///< pause length drawn uniformly in [min, max], s
  double hesitation_max_s = 0.8;
};

struct ScriptOptions {
  double dt_s = 0.02;                 ///< simulation step, s (button latching interval)
  std::optional<std::uint64_t> seed;  ///< noise seed; default: the script's `seed` (else 1)
  std::optional<NoiseParams> noise;   ///< replaces the script's `noise` block if set
  /// Multiplies tremor, overshoot and hesitation probability. 0 (default) = the expert script
  /// exactly as written; 1 = the script's `noise` block (or `noise` above) at full strength.
  double noise_scale = 0.0;
};

struct Timeline;  // resolved actions (script_timeline.h)

class ScriptSource : public InputSource {
 public:
  /// Parses and validates `yaml_text` (InputError naming file, line and field on any problem).
  ScriptSource(const std::string& yaml_text, const std::string& file, const Model& model,
               const ScriptOptions& options);
  ~ScriptSource() override;
  /// Reads the script file at `path`.
  static std::unique_ptr<ScriptSource> Open(const std::string& path, const Model& model,
                                            const ScriptOptions& options);

  /// Frame at t_s (s). Force pushes integrate their controller once per new t_s (a repeated
  /// t_s returns the same frame); calls must come in increasing t_s during a force push.
  void Frame(std::int64_t step, double t_s, InputFrame* out) override;
  /// Stores the force on each tool after the step, N (read by the next Frame's force pushes).
  void Feedback(const FeedbackFrame& feedback) override;
  /// True for t_s past the end of the last action.
  bool Finished(double t_s) const override;
  /// Copies the force-push controllers into state->script_push.
  void SaveControllers(State* state) const override;
  /// Takes the controllers from state.script_push and the fed-back forces from state.tools.
  void RestoreControllers(const State& state) override;

  /// End of the last action, s (including hesitation pauses).
  double end_time_s() const;
  /// The script's `name`.
  const std::string& name() const;

 private:
  Vec3 PushOffset(int slot, double t);

  std::unique_ptr<Timeline> timeline_;
  FeedbackFrame feedback_;
  std::array<ScriptPushState, kToolSlots> push_{};  ///< each slot's most recent force push
};

}  // namespace arthrosim::input
