// Tet tree and the exact triangle-tetrahedron test for blade cuts.
#include "arthrosim/collision/tet_query.h"

#include <algorithm>
#include <cmath>

namespace arthrosim::collision {
namespace {

// Projection interval of points onto an axis.
template <std::size_t N>
void Project(const std::array<Vec3, N>& pts, const Vec3& axis, double* lo, double* hi) {
  *lo = *hi = axis.dot(pts[0]);
  for (std::size_t i = 1; i < N; ++i) {
    const double d = axis.dot(pts[i]);
    *lo = std::min(*lo, d);
    *hi = std::max(*hi, d);
  }
}

Box TetBox(const Points& x, const mesh::Tet& t) {
  Box b;
  for (std::int32_t n : t) b.Add(x.col(n));
  return b;
}

}  // namespace

bool TriangleIntersectsTet(const Vec3& a, const Vec3& b, const Vec3& c,
                           const std::array<Vec3, 4>& tet) {
  const std::array<Vec3, 3> tri{a, b, c};
  // Scale for "this axis is zero" (parallel edges, a degenerate triangle): relative to the
  // squared size of the two shapes, so it does not depend on units.
  double size2 = 0;
  for (const Vec3& p : tet) size2 = std::max(size2, (p - tet[0]).squaredNorm());
  for (const Vec3& p : tri) size2 = std::max(size2, (p - tet[0]).squaredNorm());
  const double zero = 1e-24 * size2 * size2;
  auto separates = [&](const Vec3& axis) {
    if (axis.squaredNorm() <= zero) return false;  // not an axis: decides nothing
    double tl, th, sl, sh;
    Project(tri, axis, &tl, &th);
    Project(tet, axis, &sl, &sh);
    return th < sl || sh < tl;
  };
  const std::array<Vec3, 3> tri_edges{b - a, c - b, a - c};
  static constexpr int kEdges[6][2] = {{0, 1}, {0, 2}, {0, 3}, {1, 2}, {1, 3}, {2, 3}};
  std::array<Vec3, 6> tet_edges;
  for (int e = 0; e < 6; ++e) tet_edges[e] = tet[kEdges[e][1]] - tet[kEdges[e][0]];
  if (separates(tri_edges[0].cross(tri_edges[1]))) return false;
  static constexpr int kFaces[4][3] = {{1, 2, 3}, {0, 2, 3}, {0, 1, 3}, {0, 1, 2}};
  for (const auto& f : kFaces) {
    if (separates((tet[f[1]] - tet[f[0]]).cross(tet[f[2]] - tet[f[0]]))) return false;
  }
  for (const Vec3& te : tri_edges) {
    for (const Vec3& ee : tet_edges) {
      if (separates(te.cross(ee))) return false;
    }
  }
  // A triangle that is a point has no edge axes: the face normals decided it above; a segment
  // has its direction crossed with the tet edges (above) and the face normals.
  return true;
}

std::int32_t TetTree::BuildRange(const Points& x, const std::vector<mesh::Tet>& tets,
                                 std::vector<std::int32_t>* order, std::int32_t begin,
                                 std::int32_t end) {
  const auto id = static_cast<std::int32_t>(nodes_.size());
  nodes_.emplace_back();
  if (end - begin == 1) {
    const std::int32_t t = (*order)[static_cast<std::size_t>(begin)];
    nodes_[static_cast<std::size_t>(id)].tet = t;
    nodes_[static_cast<std::size_t>(id)].box = TetBox(x, tets[static_cast<std::size_t>(t)]);
    return id;
  }
  auto centroid = [&](std::int32_t t) {
    const mesh::Tet& e = tets[static_cast<std::size_t>(t)];
    return Vec3(x.col(e[0]) + x.col(e[1]) + x.col(e[2]) + x.col(e[3]));
  };
  Box cb;
  for (std::int32_t i = begin; i < end; ++i)
    cb.Add(centroid((*order)[static_cast<std::size_t>(i)]));
  int axis = 0;
  (cb.hi - cb.lo).maxCoeff(&axis);
  const std::int32_t mid = begin + (end - begin) / 2;
  auto first = order->begin() + begin;
  std::nth_element(first, order->begin() + mid, order->begin() + end,
                   [&](std::int32_t p, std::int32_t q) {
                     const double cp = centroid(p)[axis], cq = centroid(q)[axis];
                     return cp != cq ? cp < cq : p < q;
                   });
  const std::int32_t left = BuildRange(x, tets, order, begin, mid);
  const std::int32_t right = BuildRange(x, tets, order, mid, end);
  Node& n = nodes_[static_cast<std::size_t>(id)];
  n.left = left;
  n.right = right;
  n.box = nodes_[static_cast<std::size_t>(left)].box;
  n.box.Add(nodes_[static_cast<std::size_t>(right)].box.lo);
  n.box.Add(nodes_[static_cast<std::size_t>(right)].box.hi);
  return id;
}

void TetTree::Build(const Points& x, const std::vector<mesh::Tet>& tets) {
  nodes_.clear();
  tet_count_ = tets.size();
  built_ = true;
  depth_ = 0;
  if (tets.empty()) return;
  nodes_.reserve(2 * tets.size());
  std::vector<std::int32_t> order(tets.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = static_cast<std::int32_t>(i);
  BuildRange(x, tets, &order, 0, static_cast<std::int32_t>(order.size()));
  // Balanced median splits: depth <= ceil(log2 n).
  while ((std::size_t{1} << depth_) < tets.size()) ++depth_;
}

void TetTree::Refit(const Points& x, const std::vector<mesh::Tet>& tets) {
  // Children always follow their parent (pre-order), so a reverse sweep sees children first.
  for (std::size_t i = nodes_.size(); i-- > 0;) {
    Node& n = nodes_[i];
    if (n.tet >= 0) {
      n.box = TetBox(x, tets[static_cast<std::size_t>(n.tet)]);
    } else {
      n.box = nodes_[static_cast<std::size_t>(n.left)].box;
      n.box.Add(nodes_[static_cast<std::size_t>(n.right)].box.lo);
      n.box.Add(nodes_[static_cast<std::size_t>(n.right)].box.hi);
    }
  }
}

template <class Keep, class Leaf>
void TetTree::Traverse(const Keep& keep, const Leaf& leaf) const {
  if (nodes_.empty()) return;
  WalkBoxTree(
      nodes_, depth_, [](const Node& n) { return n.tet; }, keep, leaf);
}

void TetTree::QueryTriangle(const Points& x, const std::vector<mesh::Tet>& tets,
                            const std::vector<std::uint8_t>& alive, const Vec3& a, const Vec3& b,
                            const Vec3& c, std::vector<std::int32_t>* out) const {
  out->clear();
  Box tb;
  tb.Add(a);
  tb.Add(b);
  tb.Add(c);
  Traverse([&](const Box& box) { return box.Overlaps(tb); },
           [&](std::int32_t t) {
             if (!alive[static_cast<std::size_t>(t)]) return;
             const mesh::Tet& e = tets[static_cast<std::size_t>(t)];
             const std::array<Vec3, 4> p{x.col(e[0]), x.col(e[1]), x.col(e[2]), x.col(e[3])};
             if (TriangleIntersectsTet(a, b, c, p)) out->push_back(t);
           });
  std::sort(out->begin(), out->end());
}

void TetTree::QueryBox(const std::vector<std::uint8_t>& alive, const Box& box,
                       std::vector<std::int32_t>* out) const {
  out->clear();
  Traverse([&](const Box& b) { return b.Overlaps(box); },
           [&](std::int32_t t) {
             if (alive[static_cast<std::size_t>(t)]) out->push_back(t);
           });
  std::sort(out->begin(), out->end());
}

}  // namespace arthrosim::collision
