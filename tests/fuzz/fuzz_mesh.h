#pragma once
// The body of the four mesh targets: parse a file of one format from memory, then do what the
// product does with a parsed mesh (the `info` summary, orientation checks and the boundary
// surface the scenario loader builds).
#include <cstddef>
#include <cstdint>
#include <string>

#include "arthrosim/mesh/mesh_io.h"
#include "arthrosim/mesh/mesh_summary.h"
#include "arthrosim/mesh/mesh_validate.h"
#include "arthrosim/mesh/surface.h"
#include "fuzz_util.h"

namespace arthrosim::fuzz {

/// Parses `data` as a mesh file named `name` (its extension picks the reader).
inline void FuzzMesh(const char* name, const std::uint8_t* data, std::size_t size) {
  ExpectOnlyInputErrors([&] {
    mesh::MeshData d = mesh::ParseMesh(name, Bytes(data, size));
    mesh::FormatSummary(mesh::Summarize(d));
    if (!d.volume.tets.empty()) {
      mesh::TetMesh tets = d.volume;
      mesh::OrientAndCheck(&tets, name);
      mesh::TriMesh boundary = mesh::BoundaryTriMesh(tets);
      mesh::OrientAndCheck(&boundary, name);
    }
    if (!d.surface.tris.empty()) mesh::OrientAndCheck(&d.surface, name);
  });
}

}  // namespace arthrosim::fuzz
