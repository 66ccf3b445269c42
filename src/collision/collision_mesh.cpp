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

struct TriangleBvh::Impl {
  fcl::BVHModel<fcl::AABBd> model;
  std::vector<fcl::Vector3d> buffer;
  int tri_count = 0;
};

TriangleBvh::TriangleBvh() : impl_(std::make_unique<Impl>()) {}
TriangleBvh::~TriangleBvh() = default;
TriangleBvh::TriangleBvh(TriangleBvh&&) noexcept = default;
TriangleBvh& TriangleBvh::operator=(TriangleBvh&&) noexcept = default;

void TriangleBvh::Build(const std::vector<Vec3>& vertices, const std::vector<mesh::Tri>& tris) {
  impl_ = std::make_unique<Impl>();
  impl_->tri_count = static_cast<int>(tris.size());
  if (tris.empty()) return;
  std::vector<fcl::Triangle> ft;
  ft.reserve(tris.size());
  for (const mesh::Tri& t : tris) {
    ft.emplace_back(static_cast<std::size_t>(t[0]), static_cast<std::size_t>(t[1]),
                    static_cast<std::size_t>(t[2]));
  }
  impl_->buffer.assign(vertices.begin(), vertices.end());
  if (impl_->model.beginModel(static_cast<int>(ft.size()), static_cast<int>(vertices.size())) !=
          fcl::BVH_OK ||
      impl_->model.addSubModel(impl_->buffer, ft) != fcl::BVH_OK ||
      impl_->model.endModel() != fcl::BVH_OK) {
    throw std::runtime_error("collision: FCL failed to build a BVH");
  }
}

void TriangleBvh::Refit(const std::vector<Vec3>& vertices) {
  if (impl_->tri_count == 0) return;
  std::copy(vertices.begin(), vertices.end(), impl_->buffer.begin());
  if (impl_->model.beginReplaceModel() != fcl::BVH_OK ||
      impl_->model.replaceSubModel(impl_->buffer) != fcl::BVH_OK ||
      impl_->model.endReplaceModel(true, true) != fcl::BVH_OK) {
    throw std::runtime_error("collision: FCL failed to refit a BVH");
  }
}

bool TriangleBvh::empty() const { return impl_->tri_count == 0; }

Box TriangleBvh::Bounds() const {
  if (empty()) return Box{};
  return ToBox(impl_->model.getBV(0).bv);
}

void TriangleBvh::Query(const Box& query, std::vector<std::int32_t>* out) const {
  if (empty() || query.Empty()) return;
  const std::size_t first = out->size();
  std::vector<int> stack{0};  // depth-first, left child first
  while (!stack.empty()) {
    const auto& node = impl_->model.getBV(stack.back());
    stack.pop_back();
    if (!ToBox(node.bv).Overlaps(query)) continue;
    if (node.isLeaf()) {
      out->push_back(node.primitiveId());
    } else {
      stack.push_back(node.rightChild());
      stack.push_back(node.leftChild());
    }
  }
  std::sort(out->begin() + static_cast<std::ptrdiff_t>(first), out->end());
}

void TriangleBvh::QueryPairs(const TriangleBvh& other, double margin,
                             std::vector<std::pair<std::int32_t, std::int32_t>>* out) const {
  if (empty() || other.empty()) return;
  const std::size_t first = out->size();
  std::vector<std::pair<int, int>> stack{{0, 0}};
  while (!stack.empty()) {
    const auto [i, j] = stack.back();
    stack.pop_back();
    const auto& a = impl_->model.getBV(i);
    const auto& b = other.impl_->model.getBV(j);
    if (!ToBox(a.bv).Inflated(margin).Overlaps(ToBox(b.bv))) continue;
    if (a.isLeaf() && b.isLeaf()) {
      out->emplace_back(a.primitiveId(), b.primitiveId());
    } else if (b.isLeaf() || (!a.isLeaf() && a.bv.size() >= b.bv.size())) {
      stack.emplace_back(a.rightChild(), j);
      stack.emplace_back(a.leftChild(), j);
    } else {
      stack.emplace_back(i, b.rightChild());
      stack.emplace_back(i, b.leftChild());
    }
  }
  std::sort(out->begin() + static_cast<std::ptrdiff_t>(first), out->end());
}

}  // namespace arthrosim::collision
