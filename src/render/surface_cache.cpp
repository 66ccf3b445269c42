#include "surface_cache.h"

#include <algorithm>
#include <cstring>
#include <deque>
#include <mutex>
#include <utility>

#include "arthrosim/mesh/surface.h"

namespace arthrosim::render {
namespace {

// Enough for every body of a scenario plus a few recent cut states; older entries are dropped
// (a miss only costs a recomputation).
constexpr std::size_t kCapacity = 32;

template <class T>
bool SameBytes(const std::vector<T>& a, const std::vector<T>& b) {
  return a.size() == b.size() &&
         (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(T)) == 0);
}

bool SamePoints(const Points& a, const Points& b) {
  // equal bit patterns give bit-identical derived meshes
  return a.cols() == b.cols() && a.rows() == b.rows() &&
         (a.size() == 0 || std::memcmp(a.data(), b.data(),
                                       static_cast<std::size_t>(a.size()) * sizeof(double)) == 0);
}

struct SoftEntry {
  std::vector<mesh::Tet> tets;
  std::vector<std::uint8_t> alive;
  std::shared_ptr<const SoftTopology> topo;
};

struct BoneEntry {
  detail::BoneKey key;
  std::shared_ptr<const SceneMesh> mesh;
};

std::mutex g_mutex;
std::deque<SoftEntry> g_soft;  // most recently used first
std::deque<BoneEntry> g_bone;

template <class Entry>
void PushFront(std::deque<Entry>* list, Entry e) {
  list->push_front(std::move(e));
  if (list->size() > kCapacity) list->pop_back();
}

SoftTopology BuildTopology(const std::vector<mesh::Tet>& tets,
                           const std::vector<std::uint8_t>& alive) {
  SoftTopology topo;
  std::int32_t max_node = -1;
  for (const mesh::Tet& t : tets) {
    for (std::int32_t n : t) max_node = std::max(max_node, n);
  }
  // dense remap over the referenced node range, first-use order (as BuildScene always did)
  std::vector<std::int32_t> remap(static_cast<std::size_t>(max_node + 1), -1);
  const std::vector<mesh::BoundaryFace> faces = mesh::ExtractBoundary(tets, alive);
  topo.indices.reserve(3 * faces.size());
  for (const mesh::BoundaryFace& f : faces) {
    for (std::int32_t n : f.nodes) {
      topo.min_node = std::min(topo.min_node, n);
      topo.max_node = std::max(topo.max_node, n);
      if (n < 0) return topo;  // invalid: BuildScene reports it
      if (remap[n] < 0) {
        remap[n] = static_cast<std::int32_t>(topo.nodes.size());
        topo.nodes.push_back(n);
      }
      topo.indices.push_back(static_cast<std::uint32_t>(remap[n]));
    }
  }
  topo.closed = IsClosedSurface(topo.indices);
  return topo;
}

}  // namespace

bool IsClosedSurface(const std::vector<std::uint32_t>& indices) {
  if (indices.empty() || indices.size() % 3 != 0) return false;
  std::vector<std::pair<std::uint32_t, std::uint32_t>> edges;
  edges.reserve(indices.size());
  for (std::size_t t = 0; t < indices.size(); t += 3) {
    for (int k = 0; k < 3; ++k) edges.emplace_back(indices[t + k], indices[t + (k + 1) % 3]);
  }
  std::sort(edges.begin(), edges.end());
  for (std::size_t i = 0; i < edges.size(); ++i) {
    if (edges[i].first == edges[i].second) return false;                 // degenerate triangle
    if (i + 1 < edges.size() && edges[i + 1] == edges[i]) return false;  // edge used twice
    const std::pair<std::uint32_t, std::uint32_t> reverse(edges[i].second, edges[i].first);
    if (!std::binary_search(edges.begin(), edges.end(), reverse)) return false;
  }
  return true;
}

double SignedVolume(const SceneMesh& mesh) {
  auto p = [&](std::uint32_t i) {
    const float* v = mesh.vertices[i].pos;
    return Vec3(v[0], v[1], v[2]);
  };
  double six_v = 0;
  for (std::size_t t = 0; t + 2 < mesh.indices.size(); t += 3) {
    six_v += p(mesh.indices[t]).dot(p(mesh.indices[t + 1]).cross(p(mesh.indices[t + 2])));
  }
  return six_v / 6.0;
}

std::shared_ptr<const SoftTopology> CachedSoftTopology(const std::vector<mesh::Tet>& tets,
                                                       const std::vector<std::uint8_t>& alive) {
  {
    const std::lock_guard<std::mutex> lock(g_mutex);
    for (auto it = g_soft.begin(); it != g_soft.end(); ++it) {
      if (SameBytes(it->tets, tets) && SameBytes(it->alive, alive)) {
        SoftEntry e = std::move(*it);
        g_soft.erase(it);
        auto topo = e.topo;
        g_soft.push_front(std::move(e));
        return topo;
      }
    }
  }
  // computed outside the lock; two threads may both compute the same entry (same result)
  auto topo = std::make_shared<const SoftTopology>(BuildTopology(tets, alive));
  const std::lock_guard<std::mutex> lock(g_mutex);
  PushFront(&g_soft, SoftEntry{tets, alive, topo});
  return topo;
}

namespace detail {

std::shared_ptr<const SceneMesh> FindBone(const mesh::TriMesh& now, const Points& initial) {
  const std::lock_guard<std::mutex> lock(g_mutex);
  for (auto it = g_bone.begin(); it != g_bone.end(); ++it) {
    if (SameBytes(it->key.tris, now.tris) && SamePoints(it->key.nodes, now.nodes) &&
        SamePoints(it->key.initial, initial)) {
      BoneEntry e = std::move(*it);
      g_bone.erase(it);
      auto mesh = e.mesh;
      g_bone.push_front(std::move(e));
      return mesh;
    }
  }
  return nullptr;
}

void StoreBone(BoneKey key, std::shared_ptr<const SceneMesh> mesh) {
  const std::lock_guard<std::mutex> lock(g_mutex);
  PushFront(&g_bone, BoneEntry{std::move(key), std::move(mesh)});
}

}  // namespace detail
}  // namespace arthrosim::render
