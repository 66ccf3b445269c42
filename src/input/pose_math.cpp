#include "arthrosim/input/pose_math.h"

#include <algorithm>
#include <cmath>

namespace arthrosim::input {

double Ease(Easing easing, double s) {
  s = std::clamp(s, 0.0, 1.0);
  switch (easing) {
    case Easing::kLinear:
      return s;
    case Easing::kSmoothstep:
      return s * s * (3.0 - 2.0 * s);
    case Easing::kMinimumJerk:
      // Flash & Hogan (1985): zero velocity and acceleration at both ends.
      return s * s * s * (10.0 + s * (-15.0 + 6.0 * s));
  }
  return s;
}

std::optional<Easing> ParseEasing(const std::string& name) {
  if (name == "linear") return Easing::kLinear;
  if (name == "smoothstep") return Easing::kSmoothstep;
  if (name == "minimum_jerk") return Easing::kMinimumJerk;
  return std::nullopt;
}

Quat Slerp(const Quat& a, const Quat& b_in, double u) {
  if (u <= 0.0) return a;
  double dot = a.coeffs().dot(b_in.coeffs());
  // q and -q are the same rotation: flip b so the path is the shorter arc.
  const Quat b = dot < 0.0 ? Quat(-b_in.coeffs()) : b_in;
  if (u >= 1.0) return b;
  dot = std::abs(dot);
  double wa, wb;
  if (dot > 1.0 - 1e-12) {
    wa = 1.0 - u;  // nearly equal: linear blend avoids 0/0
    wb = u;
  } else {
    const double theta = std::acos(std::min(dot, 1.0));
    const double sin_theta = std::sin(theta);
    wa = std::sin((1.0 - u) * theta) / sin_theta;
    wb = std::sin(u * theta) / sin_theta;
  }
  Quat q(wa * a.coeffs() + wb * b.coeffs());
  q.normalize();
  return q;
}

Quat AimAlong(const Vec3& axis, double roll_rad) {
  const double n = axis.norm();
  if (!(n > 0.0)) return Quat::Identity();
  Quat q = Quat::FromTwoVectors(Vec3::UnitZ(), axis / n);
  if (roll_rad != 0.0) q = Quat(Eigen::AngleAxisd(roll_rad, axis / n)) * q;
  q.normalize();
  return q;
}

}  // namespace arthrosim::input
