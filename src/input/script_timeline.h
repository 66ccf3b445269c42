#pragma once
// Internal: a script resolved to absolute-time actions (built by script_parse.cpp, evaluated
// by script_source.cpp).
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "arthrosim/core/types.h"
#include "arthrosim/input/pose_math.h"
#include "arthrosim/input/script_source.h"

namespace arthrosim::input {

/// A hand's state at an action boundary.
struct HandState {
  std::int32_t instrument = -1;
  Vec3 portal_mm = Vec3::Zero();
  Vec3 position_mm = Vec3::Zero();
  Quat orientation = Quat::Identity();
  double jaw = 0;
  std::uint8_t held = 0;  ///< buttons held down (hold/release)
};

enum class HandOp : std::uint8_t {
  kWait,
  kPick,
  kMove,
  kPush,
  kJaw,
  kPress,
  kHold,
  kRelease,
  kWithdraw
};

/// A force-controlled push (push with `force:`): target pressing force over the action and
/// the admittance law's parameters (docs/trajectory-format.md, "Force-profile push").
struct ForceProfile {
  bool enabled = false;
  std::vector<double> t_s;      ///< keyframe times from the action start, s, increasing
  std::vector<double> force_n;  ///< target pressing force at each keyframe, N, >= 0
  double gain_mm_per_s_n = 5;   ///< depth rate per newton of force error, mm/(s N)
  double max_speed_mm_s = 10;   ///< |depth rate| limit, mm/s
  double max_depth_mm = 10;     ///< travel limit past the push's start, mm
};

/// Target force at time u (s) from the action start: linear between keyframes, held outside.
double ProfileForceAt(const ForceProfile& p, double u);

struct HandAction {
  HandOp op = HandOp::kWait;
  double t0 = 0, t1 = 0;  ///< absolute start/end, s
  Easing easing = Easing::kMinimumJerk;
  HandState start, end;
  bool aim_portal = false;           ///< orientation follows portal -> tip while moving
  double roll_rad = 0;               ///< twist about the axis for aim_portal
  std::uint8_t press_bits = 0;       ///< kPress: buttons down during [t0, t1)
  Vec3 overshoot_mm = Vec3::Zero();  ///< noise: extra excursion past the target
  ForceProfile force;                ///< kPush with a force profile (start == end then)
  int line = 0;
};

/// What the camera looks at: a fixed point or a hand's tip.
struct LookTarget {
  int slot = -1;  ///< -1: point_mm; 0/1: that slot's tip
  Vec3 point_mm = Vec3::Zero();
};

struct CameraKey {
  Vec3 position_mm = Vec3::Zero();
  LookTarget look;
  double lens_roll_rad = 0;
  double head_roll_rad = 0;
};

struct CameraAction {
  double t0 = 0, t1 = 0;
  double blend_s = 0;  ///< easing happens over [t0, t0 + blend_s], then holds
  Easing easing = Easing::kMinimumJerk;
  CameraKey start, end;
};

struct Tremor {
  std::array<std::array<double, 3>, 3> freq_hz{};  ///< [axis][component]
  std::array<std::array<double, 3>, 3> phase{};
  double amplitude_mm = 0;
};

struct Timeline {
  std::string name;
  std::string file;
  double dt_s = 0.02;
  std::array<std::vector<HandAction>, kToolSlots> hands;
  std::vector<CameraAction> camera;
  CameraKey camera_initial;
  Quat camera_initial_orientation = Quat::Identity();
  /// The scope's lens angle (Model::camera): `look_at` and `follow` aim its oblique view, not
  /// its shaft, at the target (AimScopeView).
  double camera_lens_angle_rad = 0;
  std::array<Tremor, kToolSlots> tremor;
  double end_time_s = 0;
};

/// Parses, validates and resolves a script (InputError on any problem).
Timeline BuildTimeline(const std::string& yaml_text, const std::string& file, const Model& model,
                       const ScriptOptions& options);

/// Tip position of a hand at time t, mm (no tremor, no force-push excursion).
Vec3 HandTipAt(const Timeline& tl, int slot, double t);

/// Deterministic uniform [0, 1) draw for (seed, stream, index, purpose).
double NoiseUniform(std::uint64_t seed, int stream, int index, int purpose);

}  // namespace arthrosim::input
