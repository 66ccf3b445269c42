#pragma once
// Memo of the surfaces BuildScene derives from slowly changing State data: the boundary
// topology of a soft body (changes only when tets are cut) and whole bone meshes (change only
// when burred). Entries are found by comparing the full inputs, never by a hash alone, so a hit
// returns exactly what a recomputation would; BuildScene stays a pure function of (Model, State).
#include <cstdint>
#include <memory>
#include <vector>

#include "arthrosim/core/mesh_types.h"
#include "arthrosim/core/types.h"
#include "arthrosim/render/scene.h"

namespace arthrosim::render {

/// Boundary of the alive tets as an indexed mesh over the referenced nodes only.
struct SoftTopology {
  std::vector<std::int32_t> nodes;     ///< tet-mesh node of each vertex, first-use order
  std::vector<std::uint32_t> indices;  ///< 3 per boundary face, into `nodes`
  bool closed = false;                 ///< IsClosedSurface(indices)
  std::int32_t min_node = 0;           ///< smallest referenced node (< 0: invalid input)
  std::int32_t max_node = -1;          ///< largest referenced node (-1: none)
};

/// True if every directed edge of the triangles (3 indices each) occurs once and its reverse
/// once: a closed, consistently wound surface (empty: false).
bool IsClosedSurface(const std::vector<std::uint32_t>& indices);

/// Enclosed volume of a mesh's triangles (mm^3), positive when counter-clockwise faces point
/// outward; meaningful for closed surfaces only.
double SignedVolume(const SceneMesh& mesh);

/// The boundary topology of (tets, alive) (alive empty = all alive), from the memo or computed.
/// Thread-safe.
std::shared_ptr<const SoftTopology> CachedSoftTopology(const std::vector<mesh::Tet>& tets,
                                                       const std::vector<std::uint8_t>& alive);

/// The bone mesh for (surface now, initial nodes): from the memo when all three arrays equal a
/// stored entry, else `build()` (which must be a pure function of them) stored and returned.
/// Thread-safe.
template <class Build>
std::shared_ptr<const SceneMesh> CachedBoneMesh(const mesh::TriMesh& now, const Points& initial,
                                                Build build);

namespace detail {
struct BoneKey {
  Points nodes;
  std::vector<mesh::Tri> tris;
  Points initial;
};
std::shared_ptr<const SceneMesh> FindBone(const mesh::TriMesh& now, const Points& initial);
void StoreBone(BoneKey key, std::shared_ptr<const SceneMesh> mesh);
}  // namespace detail

template <class Build>
std::shared_ptr<const SceneMesh> CachedBoneMesh(const mesh::TriMesh& now, const Points& initial,
                                                Build build) {
  if (auto hit = detail::FindBone(now, initial)) return hit;
  auto mesh = std::make_shared<const SceneMesh>(build());
  detail::StoreBone({now.nodes, now.tris, initial}, mesh);
  return mesh;
}

}  // namespace arthrosim::render
