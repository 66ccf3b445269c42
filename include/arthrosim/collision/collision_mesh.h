#pragma once
// Collision surfaces and their bounding-volume trees. A soft body's collision surface is the
// boundary of its alive tets (nodes shared with the mechanical model: an identity mapping, so
// contacts act directly on the FEM nodes). The tree topology is built by FCL (BVHModel<AABB>)
// when the topology changes; its boxes are refit every step by our own reverse sweep over a flat
// copy of the nodes (FCL's recursive refit was 10x slower; AABB refit is exact either way) and
// traversed by our own deterministic stack traversal with any conservative culling test
// (proximity to a swept tool, not only box overlap).
#include <algorithm>
#include <cstdint>
#include <utility>
#include <vector>

#include "arthrosim/core/mesh_types.h"
#include "arthrosim/core/types.h"

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

/// AABB tree over triangles. FCL (BVHModel<AABB>, its split rule) builds the topology once; the
/// nodes are then kept as a flat array that we refit and traverse ourselves: a parent always
/// precedes its children, so a refit is one reverse sweep, and a traversal needs no allocation.
/// Plain value type (copyable).
class TriangleBvh {
 public:
  /// One node: a leaf holds one triangle (`tri` >= 0, children -1); an inner node two children.
  struct Node {
    Box box;
    std::int32_t left = -1;
    std::int32_t right = -1;
    std::int32_t tri = -1;
  };

  /// Builds the tree from scratch over `tris` (indices into `vertices`, mm).
  void Build(const std::vector<Vec3>& vertices, const std::vector<mesh::Tri>& tris);
  /// Moves the vertices (same count and topology as Build) and refits the boxes bottom-up.
  void Refit(const std::vector<Vec3>& vertices);
  /// True if there are no triangles.
  bool empty() const { return nodes_.empty(); }
  /// Box of the whole surface (empty box if no triangles).
  Box Bounds() const { return empty() ? Box{} : nodes_[0].box; }
  /// Box of triangle t (as last built or refit), mm.
  const Box& TriangleBox(std::int32_t t) const { return nodes_[leaf_of_[t]].box; }
  /// Appends to *out the triangles whose box overlaps `query`, in ascending triangle index.
  void Query(const Box& query, std::vector<std::int32_t>* out) const;
  /// Appends to *out, in ascending index, the triangles whose box b satisfies keep(b), visiting
  /// only nodes whose box satisfies keep: keep must be true for a box whenever it is true for a
  /// box inside it (a conservative culling test).
  template <class Keep>
  void QueryIf(const Keep& keep, std::vector<std::int32_t>* out) const;
  /// The triangle of the leaf reached from the root by always taking the child whose box has
  /// the smaller lower(box) (the left one on a tie); -1 for an empty tree. A cheap first
  /// candidate for a nearest-triangle search (any triangle gives an upper bound).
  template <class Lower>
  std::int32_t Descend(const Lower& lower) const;
  /// Best-first branch and bound: visits the nodes whose lower(box) <= *cutoff in ascending
  /// lower(box) (ties: the smaller node index first) and calls leaf(tri, lower) for each leaf so
  /// reached; leaf may lower *cutoff (the search then stops sooner). Every triangle whose
  /// lower(box), and that of each box on its root path, stays <= the final *cutoff is reached.
  /// `heap` is scratch (its capacity is kept: no allocation once warm). Deterministic.
  template <class Lower, class Leaf>
  void BestFirst(const Lower& lower, double* cutoff, const Leaf& leaf,
                 std::vector<std::pair<double, std::int32_t>>* heap) const;
  /// Appends (this triangle, other triangle) pairs whose boxes are within `margin` mm of each
  /// other, sorted ascending.
  void QueryPairs(const TriangleBvh& other, double margin,
                  std::vector<std::pair<std::int32_t, std::int32_t>>* out) const;

 private:
  std::vector<Node> nodes_;
  std::vector<mesh::Tri> tris_;
  std::vector<std::int32_t> leaf_of_;  ///< node index of each triangle's leaf
  int depth_ = 0;                      ///< longest root-to-leaf path (edges)
};

/// Walks a binary box tree stored from its root nodes[0] (non-empty) depth-first, left child
/// first: a node whose box `keep` rejects is skipped with its subtree, and leaf(item) is called
/// for every kept leaf (item_of(node) >= 0 marks a leaf and is its item). `depth` is the longest
/// root-to-leaf path (edges); the stack, on the C++ stack unless the tree is very deep, never
/// holds more than depth + 2 entries.
template <class Node, class ItemOf, class Keep, class Leaf>
void WalkBoxTree(const std::vector<Node>& nodes, int depth, const ItemOf& item_of, const Keep& keep,
                 const Leaf& leaf) {
  constexpr int kFixed = 128;
  std::int32_t fixed[kFixed];
  std::vector<std::int32_t> heap;
  std::int32_t* stack = fixed;
  if (depth + 2 > kFixed) {
    heap.resize(static_cast<std::size_t>(depth) + 2);
    stack = heap.data();
  }
  int top = 0;
  stack[top++] = 0;
  while (top > 0) {
    const Node& node = nodes[static_cast<std::size_t>(stack[--top])];
    if (!keep(node.box)) continue;
    const std::int32_t item = item_of(node);
    if (item >= 0) {
      leaf(item);
    } else {
      stack[top++] = node.right;
      stack[top++] = node.left;
    }
  }
}

template <class Lower>
std::int32_t TriangleBvh::Descend(const Lower& lower) const {
  if (empty()) return -1;
  std::int32_t n = 0;
  while (nodes_[static_cast<std::size_t>(n)].tri < 0) {
    const Node& node = nodes_[static_cast<std::size_t>(n)];
    const double l = lower(nodes_[static_cast<std::size_t>(node.left)].box);
    const double r = lower(nodes_[static_cast<std::size_t>(node.right)].box);
    n = r < l ? node.right : node.left;
  }
  return nodes_[static_cast<std::size_t>(n)].tri;
}

template <class Lower, class Leaf>
void TriangleBvh::BestFirst(const Lower& lower, double* cutoff, const Leaf& leaf,
                            std::vector<std::pair<double, std::int32_t>>* heap) const {
  heap->clear();
  if (empty()) return;
  // A min-heap on (lower, node): the pair order makes the visit order deterministic.
  const auto later = [](const std::pair<double, std::int32_t>& a,
                        const std::pair<double, std::int32_t>& b) { return b < a; };
  const double root = lower(nodes_[0].box);
  if (!(root <= *cutoff)) return;
  heap->emplace_back(root, 0);
  while (!heap->empty()) {
    std::pop_heap(heap->begin(), heap->end(), later);
    const auto [bound, index] = heap->back();
    heap->pop_back();
    if (!(bound <= *cutoff)) break;  // every node left is at least as far
    const Node& node = nodes_[static_cast<std::size_t>(index)];
    if (node.tri >= 0) {
      leaf(node.tri, bound);
      continue;
    }
    for (const std::int32_t child : {node.left, node.right}) {
      const double l = lower(nodes_[static_cast<std::size_t>(child)].box);
      if (!(l <= *cutoff)) continue;
      heap->emplace_back(l, child);
      std::push_heap(heap->begin(), heap->end(), later);
    }
  }
}

template <class Keep>
void TriangleBvh::QueryIf(const Keep& keep, std::vector<std::int32_t>* out) const {
  if (empty()) return;
  const std::size_t first = out->size();
  WalkBoxTree(
      nodes_, depth_, [](const Node& node) { return node.tri; }, keep,
      [&](std::int32_t tri) { out->push_back(tri); });
  std::sort(out->begin() + static_cast<std::ptrdiff_t>(first), out->end());
}

}  // namespace arthrosim::collision
