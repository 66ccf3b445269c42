#include "soft_boundary.h"

#include <algorithm>
#include <array>

namespace arthrosim::render {

std::vector<mesh::Tri> AliveBoundary(const std::vector<mesh::Tet>& tets,
                                     const std::vector<std::uint8_t>& alive) {
  // outward faces of a positive tet (p0 p1 p2 p3): opposite p0, p1, p2, p3
  static constexpr int kFace[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};
  struct Face {
    std::array<std::int32_t, 3> key;  // sorted nodes
    mesh::Tri tri;                    // oriented
  };
  std::vector<Face> faces;
  faces.reserve(tets.size() * 4);
  for (std::size_t t = 0; t < tets.size(); ++t) {
    if (!alive.empty() && !alive[t]) continue;
    for (const auto& f : kFace) {
      Face face;
      face.tri = {tets[t][f[0]], tets[t][f[1]], tets[t][f[2]]};
      face.key = face.tri;
      std::sort(face.key.begin(), face.key.end());
      faces.push_back(face);
    }
  }
  // interior faces come in pairs with the same key; the key order is total apart from such
  // pairs, which are both dropped, so the result does not depend on the sort's tie order
  std::sort(faces.begin(), faces.end(), [](const Face& a, const Face& b) { return a.key < b.key; });
  std::vector<mesh::Tri> out;
  for (std::size_t i = 0; i < faces.size();) {
    std::size_t j = i + 1;
    while (j < faces.size() && faces[j].key == faces[i].key) ++j;
    if (j - i == 1) out.push_back(faces[i].tri);
    i = j;
  }
  return out;
}

}  // namespace arthrosim::render
