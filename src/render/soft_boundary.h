#pragma once
// Boundary triangles of the alive tets of a soft body: faces owned by exactly one alive tet,
// oriented outward. Cut and shaved surfaces are part of it, so they shade like any surface.
// TODO(render): switch to mesh/surface.h (BoundaryTracker) once the mesh subsystem provides it.
#include <cstdint>
#include <vector>

#include "arthrosim/mesh/tet_mesh.h"

namespace arthrosim::render {

/// Outward boundary faces of tets[i] with alive[i] != 0 (all tets if alive is empty), in a
/// deterministic order (sorted by sorted node triple). Tets must be positively oriented.
std::vector<mesh::Tri> AliveBoundary(const std::vector<mesh::Tet>& tets,
                                     const std::vector<std::uint8_t>& alive);

}  // namespace arthrosim::render
