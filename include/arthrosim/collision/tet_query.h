#pragma once
// Element queries for the operations that edit a tetrahedral body (scissors): which tets a blade
// triangle crosses. A bounding-volume tree over the tets of one body, built once per topology
// (tets appended) and refit to the current node positions before a query, so a query costs the
// refit (one pass over the tree, no allocation) plus the tets near the triangle, never an exact
// test of every element. Derived data: lives in the Workspace, rebuilt at will.
#include <array>
#include <cstdint>
#include <vector>

#include "arthrosim/collision/collision_mesh.h"
#include "arthrosim/core/mesh_types.h"
#include "arthrosim/core/types.h"

namespace arthrosim::collision {

/// True if triangle (a, b, c) and tetrahedron (p0, p1, p2, p3) share a point (touching counts),
/// by the separating-axis test (triangle normal, the four face normals, and the cross products
/// of the three triangle edges with the six tet edges). A degenerate triangle (a segment or a
/// point, e.g. closed blades) is tested as that segment or point. Any tet orientation.
bool TriangleIntersectsTet(const Vec3& a, const Vec3& b, const Vec3& c,
                           const std::array<Vec3, 4>& tet);

/// AABB tree over the tets of one body (dead tets are kept as leaves and skipped by queries, so
/// removing tets needs no rebuild; appending tets does). Plain value type.
class TetTree {
 public:
  /// True if the tree was built for exactly this many tets (appending tets needs a Build).
  bool BuiltFor(std::size_t tet_count) const { return built_ && tet_count_ == tet_count; }
  /// Builds the topology over all `tets` at positions x (3 x N, mm): median splits of the
  /// centroids along the longest axis, ties by tet index (deterministic).
  void Build(const Points& x, const std::vector<mesh::Tet>& tets);
  /// Refits every box to positions x (same tets as Build), bottom-up.
  void Refit(const Points& x, const std::vector<mesh::Tet>& tets);
  /// Replaces *out with the alive tets (ascending index) that triangle (a, b, c) intersects
  /// (TriangleIntersectsTet at positions x). The tree must be built and refit for x.
  void QueryTriangle(const Points& x, const std::vector<mesh::Tet>& tets,
                     const std::vector<std::uint8_t>& alive, const Vec3& a, const Vec3& b,
                     const Vec3& c, std::vector<std::int32_t>* out) const;
  /// Replaces *out with the alive tets (ascending index) whose box overlaps `box`.
  void QueryBox(const std::vector<std::uint8_t>& alive, const Box& box,
                std::vector<std::int32_t>* out) const;

 private:
  struct Node {
    Box box;
    std::int32_t left = -1;  ///< children (inner node); the right child follows its subtree
    std::int32_t right = -1;
    std::int32_t tet = -1;  ///< leaf: element index
  };
  std::int32_t BuildRange(const Points& x, const std::vector<mesh::Tet>& tets,
                          std::vector<std::int32_t>* order, std::int32_t begin, std::int32_t end);
  template <class Keep, class Leaf>
  void Traverse(const Keep& keep, const Leaf& leaf) const;

  std::vector<Node> nodes_;
  std::size_t tet_count_ = 0;
  bool built_ = false;
  int depth_ = 0;
};

}  // namespace arthrosim::collision
