#pragma once
// Tissues of a bone surface: triangles of a rigid body's mesh that belong to a tissue of their
// own (articular cartilage on the humeral head, the glenoid labrum), as named surface groups of
// the mesh file. The burr and awl reshape a bone surface by moving vertices and splitting edges
// (physics/bone_surface.h): triangle i < initial count stays a part of initial triangle i, the
// halves a split creates are appended. These functions carry the initial labels over to such a
// reshaped surface and to points on it.
#include <cstdint>
#include <vector>

#include "arthrosim/core/mesh_types.h"
#include "arthrosim/core/types.h"

namespace arthrosim::mesh {

/// Label of the plain bone (no tissue of its own).
inline constexpr std::int8_t kBoneTissue = -1;

/// Label of the initial triangle whose centroid is nearest to `p_mm` (ties: lowest index).
/// `labels` has one entry per triangle of `initial` (kBoneTissue or a tissue index); empty
/// labels or an empty surface give kBoneTissue.
std::int8_t TissueNear(const TriMesh& initial, const std::vector<std::int8_t>& labels,
                       const Vec3& p_mm);

/// Labels of every triangle of `now`, a surface reshaped from `initial` as described above:
/// triangle i < initial.tris.size() keeps labels[i]; an appended triangle takes the label of the
/// initial triangle whose centroid is nearest to its own (TissueNear, through a uniform grid).
/// Empty labels give all kBoneTissue. Deterministic.
std::vector<std::int8_t> TriangleTissues(const TriMesh& initial,
                                         const std::vector<std::int8_t>& labels,
                                         const TriMesh& now);

}  // namespace arthrosim::mesh
