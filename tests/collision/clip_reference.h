#pragma once
// An independent reference for "the triangle crosses the tet", shared by the collision and the
// cutting tests: clip the triangle polygon by the tet's four half-spaces (Sutherland-Hodgman);
// they intersect if anything is left.
#include <array>
#include <vector>

#include "arthrosim/core/types.h"

namespace arthrosim::collision::testing {

/// Whether triangle (a, b, c) and the tet with corners p intersect, by clipping.
inline bool ClipReference(const Vec3& a, const Vec3& b, const Vec3& c,
                          const std::array<Vec3, 4>& p) {
  std::vector<Vec3> poly{a, b, c};
  const Vec3 centroid = 0.25 * (p[0] + p[1] + p[2] + p[3]);
  static constexpr int kFaces[4][3] = {{1, 2, 3}, {0, 2, 3}, {0, 1, 3}, {0, 1, 2}};
  for (const auto& f : kFaces) {
    Vec3 n = (p[f[1]] - p[f[0]]).cross(p[f[2]] - p[f[0]]);
    if (n.dot(centroid - p[f[0]]) < 0) n = -n;  // inward
    const double off = n.dot(p[f[0]]);
    std::vector<Vec3> out;
    for (std::size_t i = 0; i < poly.size(); ++i) {
      const Vec3& s = poly[i];
      const Vec3& e = poly[(i + 1) % poly.size()];
      const double ds = n.dot(s) - off, de = n.dot(e) - off;
      if (ds >= 0) out.push_back(s);
      if ((ds >= 0) != (de >= 0)) out.push_back(s + (e - s) * (ds / (ds - de)));
    }
    poly = out;
    if (poly.empty()) return false;
  }
  return true;
}

}  // namespace arthrosim::collision::testing
