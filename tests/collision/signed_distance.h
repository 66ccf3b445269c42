#pragma once
// Test reference shared by the collision test files: the signed distance of a point from a soft
// body's surface, by brute force over every boundary triangle (independent of the trees).
#include <cmath>
#include <vector>

#include "arthrosim/collision/collision_mesh.h"
#include "arthrosim/collision/proximity.h"
#include "arthrosim/core/state.h"

namespace arthrosim::collision::testing {

/// Signed distance (mm, > 0 outside) of p from the boundary of b's alive tets, with the
/// pseudo-normal of the equally near triangles deciding the side.
inline double SignedDistance(const SoftBodyState& b, const Vec3& p) {
  double best = 1e300;
  Vec3 normal = Vec3::Zero(), delta = Vec3::Zero();
  for (const mesh::Tri& t : BoundaryTriangles(b.tets, b.tet_alive)) {
    const Vec3 a = b.x.col(t[0]), c1 = b.x.col(t[1]), c2 = b.x.col(t[2]);
    const ClosestPair c = PointTriangle(p, a, c1, c2);
    const Vec3 n = (c1 - a).cross(c2 - a).normalized();
    if (c.dist2 < best * (1 - 1e-9)) {
      best = c.dist2;
      normal = n;
      delta = p - c.pb;
    } else if (c.dist2 <= best * (1 + 1e-9)) {
      normal += n;
    }
  }
  const double d = std::sqrt(best);
  return delta.dot(normal) >= 0 ? d : -d;
}

}  // namespace arthrosim::collision::testing
