#include "bone_contact.h"

#include <algorithm>
#include <cmath>

#include "arthrosim/collision/proximity.h"

namespace arthrosim::instruments {

Vec3 PressMm(const ToolState& tool) { return tool.handle_pose.position_mm - tool.pose.position_mm; }

BoneTouch TouchBone(const mesh::TriMesh& surface, const Vec3& a, const Vec3& b, double radius_mm) {
  BoneTouch out;
  const Vec3 lo = a.cwiseMin(b) - Vec3::Constant(radius_mm);
  const Vec3 hi = a.cwiseMax(b) + Vec3::Constant(radius_mm);
  const collision::Simplex core =
      (a - b).norm() > 0 ? collision::SegmentSimplex(a, b) : collision::PointSimplex(a);
  Vec3 sum = Vec3::Zero(), normal = Vec3::Zero();
  for (const mesh::Tri& t : surface.tris) {
    const Vec3 p0 = surface.nodes.col(t[0]), p1 = surface.nodes.col(t[1]),
               p2 = surface.nodes.col(t[2]);
    const Vec3 tlo = p0.cwiseMin(p1).cwiseMin(p2), thi = p0.cwiseMax(p1).cwiseMax(p2);
    if ((tlo.array() > hi.array()).any() || (thi.array() < lo.array()).any()) continue;
    const collision::ClosestPair c =
        collision::Closest(core, collision::TriangleSimplex(p0, p1, p2));
    const double d = std::sqrt(c.dist2);
    if (d > radius_mm) continue;
    ++out.triangles;
    sum += c.pb;
    normal += (p1 - p0).cross(p2 - p0);
    out.deepest_mm = std::max(out.deepest_mm, radius_mm - d);
  }
  if (out.triangles > 0) {
    out.center_mm = sum / out.triangles;
    if (normal.norm() > 0) out.normal = normal.normalized();
  }
  return out;
}

}  // namespace arthrosim::instruments
