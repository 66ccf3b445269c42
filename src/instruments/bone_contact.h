#pragma once
// Where a rounded tool part touches a bone surface: shared by the burr and the awl.
#include "arthrosim/core/mesh_types.h"
#include "arthrosim/core/state.h"

namespace arthrosim::instruments {

/// The surface points of a bone within `radius_mm` of a point or segment core.
struct BoneTouch {
  int triangles = 0;              ///< triangles within reach
  Vec3 center_mm = Vec3::Zero();  ///< mean of their closest points to the core, mm
  Vec3 normal = Vec3::Zero();     ///< area-weighted outward normal of those triangles (unit)
  double deepest_mm = 0;          ///< max(radius - distance) over them, mm (>= 0)
};

/// How far the hand presses the tool into what holds its proxy: handle tip minus proxy tip, mm
/// (zero when the proxy is off or free, since the tool then is where the hand is). Burr and awl
/// act at the proxy advanced along this press: the proxy stops at the bone surface, and the bone
/// gives way only as far as the operation removes it (the issue's "advance only as far as
/// material is removed").
Vec3 PressMm(const ToolState& tool);

/// Closest points of the surface to segment (a, b) (a == b: a point) within radius_mm.
BoneTouch TouchBone(const mesh::TriMesh& surface, const Vec3& a, const Vec3& b, double radius_mm);

}  // namespace arthrosim::instruments
