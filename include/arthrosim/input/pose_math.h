#pragma once
// Small pose helpers shared by the input sources: easing curves, shortest-arc slerp, aiming.
// Conventions (core/model.h): a tool's shaft runs along -z from the tip, so its +z axis points
// from the portal to the tip; the arthroscope's shaft axis is its +z as well.
#include <cstdint>
#include <optional>
#include <string>

#include "arthrosim/core/types.h"

namespace arthrosim::input {

enum class Easing : std::uint8_t { kLinear, kSmoothstep, kMinimumJerk };

/// Easing value e(s) for s in [0, 1] (clamped): e(0) = 0, e(1) = 1, monotone.
double Ease(Easing easing, double s);
/// "linear", "smoothstep", "minimum_jerk"; std::nullopt if unknown.
std::optional<Easing> ParseEasing(const std::string& name);

/// Shortest-arc spherical interpolation of unit quaternions, u in [0, 1]; exact at u = 0 and 1
/// (returns a or the sign-aligned b), normalised result.
Quat Slerp(const Quat& a, const Quat& b, double u);

/// Orientation whose +z axis points along `axis` (any length > 0) with no twist relative to the
/// minimal rotation from world +z, then rotated by roll_rad about that axis.
Quat AimAlong(const Vec3& axis, double roll_rad = 0.0);

/// Linear interpolation a + (b - a) * u, exact at u = 0 (returns a).
inline Vec3 Lerp(const Vec3& a, const Vec3& b, double u) {
  if (u == 0.0) return a;
  if (u == 1.0) return b;
  return a + (b - a) * u;
}
inline double Lerp(double a, double b, double u) {
  if (u == 0.0) return a;
  if (u == 1.0) return b;
  return a + (b - a) * u;
}

}  // namespace arthrosim::input
