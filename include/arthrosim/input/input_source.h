#pragma once
// One interface for every input: recorded sessions, synthetic scripts, live devices. The
// deterministic core calls Frame once per step and Feedback after it; it never knows which
// source it has. File sources and scripts without force pushes are pure functions of the step
// time (so a run can be restored mid-way); a script's force push also depends on the forces fed
// back (deterministic, since they come from the core); only the live server depends on what
// arrives over the network.
#include <cstdint>
#include <map>
#include <optional>
#include <string>

#include "arthrosim/core/input_frame.h"
#include "arthrosim/core/model.h"
#include "arthrosim/core/state.h"

namespace arthrosim::input {

/// The three input devices of a session: two instrument slots (hands) and the arthroscope.
enum class Device : std::uint8_t { kSlot0 = 0, kSlot1 = 1, kScope = 2 };
inline constexpr int kDeviceCount = 3;

/// "slot0", "slot1", "scope".
const char* DeviceName(Device device);
/// Parses "slot0", "slot1", "scope" (alias "camera"); std::nullopt otherwise.
std::optional<Device> ParseDevice(const std::string& name);

/// TRANSFORM device names a live server accepts besides its own (Slot0ToReference, ...): name ->
/// the device it drives, or std::nullopt for a name whose messages are ignored without a log
/// line (a tracker's other tools). A name here replaces a default of the same name.
using IgtlDeviceNames = std::map<std::string, std::optional<Device>>;

class InputSource {
 public:
  virtual ~InputSource() = default;
  /// Fills *out with the command for the step at simulated time t_s (s). t_s should be
  /// step * dt; buttons pressed at any time in (t_s - dt, t_s] are reported as pressed.
  virtual void Frame(std::int64_t step, double t_s, InputFrame* out) = 0;
  /// Force on each slot after the step, N, world (sent to a haptic device, used by a script's
  /// force push; ignored by file sources). Call after every Step, before the next Frame.
  virtual void Feedback(const FeedbackFrame& feedback) { (void)feedback; }
  /// A line for the trainee (live feedback, e.g. a warning) about simulated time t_s (s). A live
  /// source delivers it to the device side; file sources and scripts ignore it.
  virtual void Notify(const std::string& text, double t_s) {
    (void)text;
    (void)t_s;
  }
  /// True once the source has nothing more to say at time t_s (s); the run may stop.
  virtual bool Finished(double t_s) const = 0;
  /// How far behind real time (s) the last Frame was asked for: > 0 when the steps take longer
  /// than the simulated time they cover. 0 for sources not paced to the wall clock.
  virtual double RealtimeLagS() const { return 0; }
  /// Copies what the source's future frames depend on besides the step time and the State
  /// (a script's force-push controllers) into *state. Call after every Frame, before the Step.
  /// Default: nothing (pure sources).
  virtual void SaveControllers(State* state) const { (void)state; }
  /// Restores the controllers and the last fed-back forces from a State saved by
  /// SaveControllers (a checkpoint), so the next Frame continues exactly as the saved run did.
  virtual void RestoreControllers(const State& state) { (void)state; }
};

/// The frame of a source with nothing inserted: both slots withdrawn, scope at its initial pose.
InputFrame IdleFrame(const Model& model);

/// A source that never moves anything (IdleFrame forever; never finished).
class IdleSource : public InputSource {
 public:
  explicit IdleSource(const Model& model) : frame_(IdleFrame(model)) {}
  void Frame(std::int64_t, double, InputFrame* out) override { *out = frame_; }
  bool Finished(double) const override { return false; }

 private:
  InputFrame frame_;
};

/// Bit-for-bit equality of two frames (every double compared by its bit pattern).
bool BitwiseEqual(const InputFrame& a, const InputFrame& b);

}  // namespace arthrosim::input
