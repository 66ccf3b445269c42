#pragma once
// Collision surfaces and their bounding-volume trees. A soft body's collision surface is the
// boundary of its alive tets (nodes shared with the mechanical model: an identity mapping, so
// contacts act directly on the FEM nodes). The tree is an FCL BVHModel<AABB>, refit every step
// (bottom-up refit is exact for AABB; it is RSS/OBBRSS that 0.7 corrupts) and rebuilt when the
// topology changes. Candidate queries traverse FCL's boxes with our own deterministic stack
// traversal, so a query can be inflated by a margin (proximity, not only overlap).
#include <cstdint>
#include <memory>
#include <utility>
#include <vector>

#include "arthrosim/core/types.h"
#include "arthrosim/mesh/tet_mesh.h"

namespace arthrosim::collision {

/// Axis-aligned box, mm.
struct Box {
  Vec3 lo = Vec3::Constant(1e300);
  Vec3 hi = Vec3::Constant(-1e300);
  /// Grows the box to contain p.
  void Add(const Vec3& p) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  /// The box grown by m on every side.
  Box Inflated(double m) const { return Box{lo.array() - m, hi.array() + m}; }
  /// True if the boxes share a point.
  bool Overlaps(const Box& o) const {
    return (lo.array() <= o.hi.array()).all() && (o.lo.array() <= hi.array()).all();
  }
  bool Empty() const { return (lo.array() > hi.array()).any(); }
};

/// Boundary triangles of the alive tets, outward (right-hand rule), each rotated so its smallest
/// node id comes first, sorted by node ids: the result does not depend on tet order.
std::vector<mesh::Tri> BoundaryTriangles(const std::vector<mesh::Tet>& tets,
                                         const std::vector<std::uint8_t>& alive);

/// Each triangle rotated (orientation kept) so its smallest node id is first, then sorted: a
/// canonical form that makes results independent of the input triangle order and rotation.
std::vector<mesh::Tri> CanonicalTriangles(std::vector<mesh::Tri> tris);

/// A triangle surface indexed by node ids of a larger node array, with local vertex numbering.
struct Surface {
  std::vector<mesh::Tri> tris;                 ///< global node ids (as in BoundaryTriangles)
  std::vector<std::int32_t> vertices;          ///< sorted unique global node ids used by tris
  std::vector<mesh::Tri> local_tris;           ///< tris in indices into `vertices`
  std::vector<std::int32_t> vertex_tri_start;  ///< CSR: triangles around local vertex v are
  std::vector<std::int32_t> vertex_tris;       ///< vertex_tris[start[v] .. start[v+1])
};

/// Builds the local numbering and vertex->triangle adjacency of a set of triangles.
Surface MakeSurface(std::vector<mesh::Tri> tris);

/// FCL AABB tree over triangles. Not copyable (FCL owns raw buffers); movable.
class TriangleBvh {
 public:
  TriangleBvh();
  ~TriangleBvh();
  TriangleBvh(TriangleBvh&&) noexcept;
  TriangleBvh& operator=(TriangleBvh&&) noexcept;

  /// Builds the tree from scratch over `tris` (indices into `vertices`, mm).
  void Build(const std::vector<Vec3>& vertices, const std::vector<mesh::Tri>& tris);
  /// Moves the vertices (same count and topology as Build) and refits the boxes bottom-up.
  void Refit(const std::vector<Vec3>& vertices);
  /// True if there are no triangles.
  bool empty() const;
  /// Box of the whole surface (empty box if no triangles).
  Box Bounds() const;
  /// Appends to *out the triangles whose box overlaps `query`, in ascending triangle index.
  void Query(const Box& query, std::vector<std::int32_t>* out) const;
  /// Appends (this triangle, other triangle) pairs whose boxes are within `margin` mm of each
  /// other, sorted ascending.
  void QueryPairs(const TriangleBvh& other, double margin,
                  std::vector<std::pair<std::int32_t, std::int32_t>>* out) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace arthrosim::collision
