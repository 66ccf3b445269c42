#pragma once
// Basic value types shared by every layer. Lengths are millimetres unless a name says otherwise.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>
#include <cstdint>

namespace arthrosim {

using Vec3 = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3d;
using Quat = Eigen::Quaterniond;
/// Node coordinates, one column per node (3 x N), millimetres. Column-major, so node i's xyz
/// are contiguous: the memory layout of an HDF5 [N, 3] row-major dataset.
using Points = Eigen::Matrix3Xd;

/// A rigid pose: position (mm) and orientation (unit quaternion, w x y z), body to world.
struct Pose {
  Vec3 position_mm = Vec3::Zero();
  Quat orientation = Quat::Identity();

  /// Maps a point given in the pose's local frame (mm) to world coordinates (mm).
  Vec3 Apply(const Vec3& local) const { return position_mm + orientation * local; }
  /// Equality of every bit (for determinism checks).
  bool operator==(const Pose& o) const {
    return position_mm == o.position_mm && orientation.coeffs() == o.orientation.coeffs();
  }
};

/// Orientation whose +z axis (forward, see the tool-frame convention in model.h) points from
/// `eye` to `target` and whose +y (image up) is as close as possible to world +z (world +y when
/// looking straight up or down). Identity if eye == target.
inline Quat LookAtOrientation(const Vec3& eye, const Vec3& target) {
  Vec3 forward = target - eye;
  const double n = forward.norm();
  if (!(n > 0.0)) return Quat::Identity();
  forward /= n;
  const Vec3 up = std::abs(forward.z()) > 1.0 - 1e-9 ? Vec3::UnitY() : Vec3::UnitZ();
  const Vec3 x = up.cross(forward).normalized();
  Mat3 r;
  r.col(0) = x;
  r.col(1) = forward.cross(x);
  r.col(2) = forward;
  return Quat(r).normalized();
}

}  // namespace arthrosim
