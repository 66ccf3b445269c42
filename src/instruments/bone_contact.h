#pragma once
// Where a rounded tool part touches a bone surface: shared by the burr and the awl.
#include "arthrosim/core/state.h"
#include "arthrosim/mesh/tet_mesh.h"

namespace arthrosim::instruments {

/// The surface points of a bone within `radius_mm` of a point or segment core.
struct BoneTouch {
  int triangles = 0;              ///< triangles within reach
  Vec3 center_mm = Vec3::Zero();  ///< mean of their closest points to the core, mm
  Vec3 normal = Vec3::Zero();     ///< area-weighted outward normal of those triangles (unit)
  double deepest_mm = 0;          ///< max(radius - distance) over them, mm (>= 0)
};

/// Closest points of the surface to segment (a, b) (a == b: a point) within radius_mm.
BoneTouch TouchBone(const mesh::TriMesh& surface, const Vec3& a, const Vec3& b, double radius_mm);

}  // namespace arthrosim::instruments
