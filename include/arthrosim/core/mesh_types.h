#pragma once
// Plain mesh containers, in core because Model and State hold them (the mesh subsystem reads and
// writes them). Coordinates in millimetres; indices 0-based.
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "arthrosim/core/types.h"

namespace arthrosim::mesh {

using Tet = std::array<std::int32_t, 4>;
using Tri = std::array<std::int32_t, 3>;
using Edge = std::array<std::int32_t, 2>;

/// A tetrahedral mesh. Positive orientation: (p1-p0).dot((p2-p0).cross(p3-p0)) > 0.
struct TetMesh {
  Points nodes;           ///< 3 x N, mm
  std::vector<Tet> tets;  ///< node indices
};

/// A triangle surface mesh; outward normal by the right-hand rule on (p0, p1, p2).
struct TriMesh {
  Points nodes;           ///< 3 x N, mm
  std::vector<Tri> tris;  ///< node indices
};

/// A polyline (suture thread in a mesh file): nodes and segments.
struct LineMesh {
  Points nodes;             ///< 3 x N, mm
  std::vector<Edge> edges;  ///< node indices
};

}  // namespace arthrosim::mesh
