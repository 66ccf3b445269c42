#pragma once
// Checks meshes once at load: fixes what is safe to fix (orientation), reports what physics
// should know (degenerate elements), and throws InputError for what makes a mesh unusable.
#include <cstdint>
#include <string>
#include <vector>

#include "arthrosim/core/mesh_types.h"

namespace arthrosim::mesh {

/// Relative threshold: an element is degenerate if |6V| <= kDegenerateTol * L^3 (tets) or
/// |2A| <= kDegenerateTol * L^2 (triangles), L = its longest edge.
inline constexpr double kDegenerateTol = 1e-12;

struct TetQualityReport {
  std::int64_t num_tets = 0;
  std::int64_t num_reoriented = 0;          ///< inverted tets fixed by swapping nodes 2 and 3
  std::vector<std::int32_t> degenerate;     ///< indices of degenerate tets (left as they are)
  std::int64_t num_unreferenced_nodes = 0;  ///< nodes used by no tet (they get no mass)
  double min_volume = 0;                    ///< mm^3, after reorientation (0 if no tets)
  double max_volume = 0;                    ///< mm^3
  double total_volume = 0;                  ///< mm^3, sum over tets after reorientation
};

struct TriQualityReport {
  std::int64_t num_tris = 0;
  std::vector<std::int32_t> degenerate;  ///< indices of degenerate triangles
  std::int64_t num_unreferenced_nodes = 0;
  bool closed = false;                 ///< every edge shared by exactly two triangles
  bool consistently_oriented = false;  ///< every shared edge used in opposite directions
  bool flipped = false;                ///< closed+consistent but inward: all were reversed
  double area = 0;                     ///< mm^2
  double enclosed_volume = 0;          ///< mm^3 after any flip (meaningful if closed)
};

/// Signed volume of tet t (mm^3), positive for the orientation documented in core/mesh_types.h.
double TetSignedVolume(const Points& nodes, const Tet& t);
/// Sum of signed tet volumes (mm^3), in tet order.
double TotalVolume(const TetMesh& m);
/// Volume enclosed by a triangle surface by the divergence theorem (mm^3); exact (up to
/// rounding) for a closed surface, positive when it is outward oriented.
double EnclosedVolume(const TriMesh& m);

/// Validates a tet mesh: InputError (naming `file`) on out-of-range or repeated node indices
/// and non-finite coordinates; reorients inverted tets; reports degenerate ones.
TetQualityReport OrientAndCheck(TetMesh* m, const std::string& file);
/// Validates a triangle surface like the tet version; if the surface is closed and consistently
/// oriented but encloses negative volume, reverses every triangle so it faces outward.
TriQualityReport OrientAndCheck(TriMesh* m, const std::string& file);

/// Drops nodes used by no tet, renumbering the rest in their original order. Returns the map
/// old index -> new index (-1 for dropped nodes), so groups or other meshes can be remapped.
std::vector<std::int32_t> RemoveUnreferencedNodes(TetMesh* m);

}  // namespace arthrosim::mesh
