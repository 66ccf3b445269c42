#include "arthrosim/collision/collision_mesh.h"

#include "arthrosim/mesh/surface.h"

#include <algorithm>
#include <stdexcept>

#include <fcl/geometry/bvh/BVH_model.h>
#include <fcl/math/bv/AABB.h>
#include <fcl/math/bv/utility.h>

namespace arthrosim::collision {
namespace {

mesh::Tri Canonical(const mesh::Tri& t) {
  // Rotate (keeps orientation) so the smallest id is first.
  if (t[1] < t[0] && t[1] < t[2]) return {t[1], t[2], t[0]};
  if (t[2] < t[0] && t[2] < t[1]) return {t[2], t[0], t[1]};
  return t;
}

Box ToBox(const fcl::AABBd& b) { return Box{b.min_, b.max_}; }

}  // namespace

std::vector<mesh::Tri> BoundaryTriangles(const std::vector<mesh::Tet>& tets,
                                         const std::vector<std::uint8_t>& alive) {
  // The mesh layer's extraction orders faces by tet; the canonical form removes that order.
  std::vector<mesh::Tri> tris;
  for (const mesh::BoundaryFace& f : mesh::ExtractBoundary(tets, alive)) tris.push_back(f.nodes);
  return CanonicalTriangles(std::move(tris));
}

std::vector<mesh::Tri> CanonicalTriangles(std::vector<mesh::Tri> tris) {
  for (mesh::Tri& t : tris) t = Canonical(t);
  std::sort(tris.begin(), tris.end());
  return tris;
}

Surface MakeSurface(std::vector<mesh::Tri> tris) {
  Surface s;
  s.tris = std::move(tris);
  for (const mesh::Tri& t : s.tris) s.vertices.insert(s.vertices.end(), t.begin(), t.end());
  std::sort(s.vertices.begin(), s.vertices.end());
  s.vertices.erase(std::unique(s.vertices.begin(), s.vertices.end()), s.vertices.end());
  s.local_tris.reserve(s.tris.size());
  std::vector<std::int32_t> count(s.vertices.size() + 1, 0);
  for (const mesh::Tri& t : s.tris) {
    mesh::Tri l;
    for (int k = 0; k < 3; ++k) {
      l[k] = static_cast<std::int32_t>(
          std::lower_bound(s.vertices.begin(), s.vertices.end(), t[k]) - s.vertices.begin());
      ++count[l[k] + 1];
    }
    s.local_tris.push_back(l);
  }
  for (std::size_t v = 1; v < count.size(); ++v) count[v] += count[v - 1];
  s.vertex_tri_start = count;
  s.vertex_tris.assign(s.tris.size() * 3, 0);
  for (std::size_t t = 0; t < s.local_tris.size(); ++t) {
    for (int k = 0; k < 3; ++k) s.vertex_tris[count[s.local_tris[t][k]]++] = static_cast<int>(t);
  }
  return s;
}

void TriangleBvh::Build(const std::vector<Vec3>& vertices, const std::vector<mesh::Tri>& tris) {
  nodes_.clear();
  leaf_of_.assign(tris.size(), -1);
  tris_ = tris;
  depth_ = 0;
  if (tris.empty()) return;
  std::vector<fcl::Triangle> ft;
  ft.reserve(tris.size());
  for (const mesh::Tri& t : tris) {
    ft.emplace_back(static_cast<std::size_t>(t[0]), static_cast<std::size_t>(t[1]),
                    static_cast<std::size_t>(t[2]));
  }
  std::vector<fcl::Vector3d> buffer(vertices.begin(), vertices.end());
  fcl::BVHModel<fcl::AABBd> model;
  if (model.beginModel(static_cast<int>(ft.size()), static_cast<int>(vertices.size())) !=
          fcl::BVH_OK ||
      model.addSubModel(buffer, ft) != fcl::BVH_OK || model.endModel() != fcl::BVH_OK) {
    throw std::runtime_error("collision: FCL failed to build a BVH");
  }
  nodes_.resize(static_cast<std::size_t>(model.getNumBVs()));
  std::vector<int> depth(nodes_.size(), 0);
  for (std::size_t i = 0; i < nodes_.size(); ++i) {
    const auto& b = model.getBV(static_cast<int>(i));
    Node& n = nodes_[i];
    n.box = ToBox(b.bv);
    if (b.isLeaf()) {
      n.tri = b.primitiveId();
      leaf_of_.at(static_cast<std::size_t>(n.tri)) = static_cast<std::int32_t>(i);
    } else {
      n.left = b.leftChild();
      n.right = b.rightChild();
      // The reverse-sweep refit needs children after their parent (FCL allocates them so).
      if (n.left <= static_cast<int>(i) || n.right <= static_cast<int>(i)) {
        throw std::runtime_error("collision: unexpected BVH node order");
      }
      depth[n.left] = depth[n.right] = depth[i] + 1;
      depth_ = std::max(depth_, depth[i] + 1);
    }
  }
  for (std::int32_t l : leaf_of_) {
    if (l < 0) throw std::runtime_error("collision: BVH lost a triangle");
  }
  Refit(vertices);  // boxes from our own fit, so a built and a refit tree agree bit for bit
}

void TriangleBvh::Refit(const std::vector<Vec3>& v) {
  for (std::size_t i = nodes_.size(); i-- > 0;) {
    Node& n = nodes_[i];
    if (n.tri >= 0) {
      const mesh::Tri& t = tris_[static_cast<std::size_t>(n.tri)];
      n.box.lo = v[t[0]].cwiseMin(v[t[1]]).cwiseMin(v[t[2]]);
      n.box.hi = v[t[0]].cwiseMax(v[t[1]]).cwiseMax(v[t[2]]);
    } else {
      n.box.lo = nodes_[n.left].box.lo.cwiseMin(nodes_[n.right].box.lo);
      n.box.hi = nodes_[n.left].box.hi.cwiseMax(nodes_[n.right].box.hi);
    }
  }
}

void TriangleBvh::Query(const Box& query, std::vector<std::int32_t>* out) const {
  if (query.Empty()) return;
  QueryIf([&](const Box& b) { return b.Overlaps(query); }, out);
}

void TriangleBvh::QueryPairs(const TriangleBvh& other, double margin,
                             std::vector<std::pair<std::int32_t, std::int32_t>>* out) const {
  if (empty() || other.empty()) return;
  const std::size_t first = out->size();
  auto size = [](const Box& b) { return (b.hi - b.lo).squaredNorm(); };
  // Depth-first; every pop descends one level in one tree and leaves at most one sibling
  // pending, so the stack never holds more than depth_ + other.depth_ + 1 pairs: a fixed array
  // for every mesh of the scene, the heap only for degenerate trees.
  constexpr int kFixed = 256;
  std::pair<int, int> fixed[kFixed];
  std::vector<std::pair<int, int>> heap;
  std::pair<int, int>* stack = fixed;
  if (depth_ + other.depth_ + 1 > kFixed) {
    heap.resize(static_cast<std::size_t>(depth_ + other.depth_) + 1);
    stack = heap.data();
  }
  int top = 0;
  stack[top++] = {0, 0};
  while (top > 0) {
    const auto [i, j] = stack[--top];
    const Node& a = nodes_[i];
    const Node& b = other.nodes_[j];
    if (!a.box.Inflated(margin).Overlaps(b.box)) continue;
    const bool la = a.tri >= 0, lb = b.tri >= 0;
    if (la && lb) {
      out->emplace_back(a.tri, b.tri);
    } else if (lb || (!la && size(a.box) >= size(b.box))) {
      stack[top++] = {a.right, j};
      stack[top++] = {a.left, j};
    } else {
      stack[top++] = {i, b.right};
      stack[top++] = {i, b.left};
    }
  }
  std::sort(out->begin() + static_cast<std::ptrdiff_t>(first), out->end());
}

}  // namespace arthrosim::collision
