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

}  // namespace arthrosim
