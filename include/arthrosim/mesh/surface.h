#pragma once
// Boundary surfaces of tetrahedral meshes. Boundary faces keep the tet mesh's node indices
// (no renumbering), so physics, rendering and collision share one numbering. Local face f of a
// tet is the face opposite its node f; with positively oriented tets the node order below makes
// every boundary face outward by the right-hand rule.
#include <array>
#include <cstdint>
#include <map>
#include <set>
#include <utility>
#include <vector>

#include "arthrosim/core/mesh_types.h"

namespace arthrosim::mesh {

/// Local node positions (0..3) of face f (opposite node f), outward for a positive tet.
inline constexpr std::array<std::array<int, 3>, 4> kTetFaces = {
    {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}}};

/// One boundary face: its three node indices (outward order) and where it comes from.
struct BoundaryFace {
  Tri nodes{};           ///< indices into the tet mesh's nodes
  std::int32_t tet = 0;  ///< owning tetrahedron
  std::int8_t face = 0;  ///< local face 0..3 (opposite node `face`)
  bool operator==(const BoundaryFace& o) const {
    return nodes == o.nodes && tet == o.tet && face == o.face;
  }
};

/// The node indices of local face f of tet t, outward if t is positively oriented.
Tri TetFace(const Tet& t, int f);

/// Faces that belong to exactly one alive tet, sorted by (tet, face). `alive` (size = tets, or
/// empty = all alive) masks removed tets. Faces shared by 3+ tets (invalid) count as interior.
std::vector<BoundaryFace> ExtractBoundary(const std::vector<Tet>& tets,
                                          const std::vector<std::uint8_t>& alive = {});

/// The boundary as a TriMesh with the SAME node array and indices as `m` (unused nodes kept).
TriMesh BoundaryTriMesh(const TetMesh& m, const std::vector<std::uint8_t>& alive = {});

/// Incrementally maintained boundary of a changing tet set (cutting/tearing). Faces get stable
/// ids, so RemoveTet/ReviveTet touch only the tet's 4 face records plus O(log B) boundary-set
/// updates; AddTet adds an O(log F) key lookup per face. Output order is deterministic (sorted
/// by tet, face).
class BoundaryTracker {
 public:
  BoundaryTracker() = default;
  /// Starts from `tets`; `alive` as in ExtractBoundary (empty = all alive).
  explicit BoundaryTracker(std::vector<Tet> tets, const std::vector<std::uint8_t>& alive = {});

  /// Marks tet t removed; no effect if it is already removed. Throws std::out_of_range on a
  /// bad index.
  void RemoveTet(std::int32_t t);
  /// Appends a new alive tet (e.g. from splitting) and returns its index (= previous count), which
  /// must match the index the caller gives it in its own tet list.
  std::int32_t AddTet(const Tet& tet);
  /// Revives a previously removed tet t (no effect if alive).
  void ReviveTet(std::int32_t t);

  /// Current boundary faces sorted by (tet, face); equals ExtractBoundary(tets(), alive()).
  std::vector<BoundaryFace> Faces() const;
  std::size_t num_faces() const { return boundary_.size(); }
  const std::vector<Tet>& tets() const { return tets_; }
  const std::vector<std::uint8_t>& alive() const { return alive_; }

 private:
  using FaceKey = std::array<std::int32_t, 3>;             // sorted node indices
  using Incidence = std::pair<std::int32_t, std::int8_t>;  // (tet, local face)
  /// Face id of `key`, creating a record if it is new (only AddTet needs the key lookup).
  std::int32_t FaceId(const FaceKey& key);
  void Attach(std::int32_t t);
  void Detach(std::int32_t t);
  void Refresh(std::int32_t face);

  std::vector<Tet> tets_;
  std::vector<std::uint8_t> alive_;
  std::vector<std::array<std::int32_t, 4>> tet_faces_;  // face id of each local face
  std::vector<std::vector<Incidence>> incidences_;      // alive incidences per face id, sorted
  std::map<FaceKey, std::int32_t> face_ids_;            // key -> face id
  std::set<Incidence> boundary_;                        // faces with exactly one alive tet
};

}  // namespace arthrosim::mesh
