#include "arthrosim/core/scope_aim.h"

#include <algorithm>
#include <cmath>

namespace arthrosim {

Vec3 ScopeViewDirectionLocal(double lens_angle_rad) {
  return Vec3(0.0, std::sin(lens_angle_rad), std::cos(lens_angle_rad));
}

Quat AimScopeView(const Vec3& eye, const Vec3& target, double lens_angle_rad, const Vec3& up_hint) {
  Vec3 f = target - eye;
  const double n = f.norm();
  if (!(n > 0.0)) return Quat::Identity();
  f /= n;
  // image up: the hint made orthogonal to the view; world +y, then any, when it is parallel
  Vec3 u = up_hint - up_hint.dot(f) * f;
  if (u.norm() <= 1e-9 * std::max(1.0, up_hint.norm())) u = Vec3::UnitY() - f.y() * f;
  u = u.norm() > 1e-9 ? Vec3(u.normalized()) : Vec3(f.unitOrthogonal());
  // The tip frame's +y and +z in world: the view f = sin(a) y + cos(a) z and the image up
  // u = cos(a) y - sin(a) z, solved for y and z.
  const double sa = std::sin(lens_angle_rad), ca = std::cos(lens_angle_rad);
  const Vec3 y = sa * f + ca * u, z = ca * f - sa * u;
  Mat3 r;
  r.col(0) = y.cross(z);
  r.col(1) = y;
  r.col(2) = z;
  return Quat(r).normalized();
}

}  // namespace arthrosim
