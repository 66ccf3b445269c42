#pragma once
// Reading and writing mesh files. Supported: Gmsh .msh (2.2 ASCII, 4.1 ASCII, 4.1 binary),
// legacy VTK .vtk (UNSTRUCTURED_GRID, ASCII, versions 2.0-5.1), Wavefront .obj, STL (ASCII and
// binary). Coordinates are taken as millimetres as written. Every problem in a file throws
// arthrosim::InputError naming the file, the 1-based line (ASCII) or the byte offset (binary,
// in the message), the field and what was expected.
#include <cstdint>
#include <string>
#include <vector>

#include "arthrosim/core/mesh_types.h"

namespace arthrosim::mesh {

/// A named element set. For Gmsh files these are the physical groups; for OBJ files the
/// `g`/`o` names (dim 2 or 1). Element indices refer to MeshData::volume.tets (dim 3),
/// surface.tris (dim 2) or lines.edges (dim 1), ascending, no duplicates.
struct PhysicalGroup {
  int dim = 0;                         ///< 1 lines, 2 triangles, 3 tetrahedra
  int tag = 0;                         ///< the file's physical tag (> 0 for Gmsh)
  std::string name;                    ///< "" if the file gave no name
  std::vector<std::int32_t> elements;  ///< indices into the element list of that dimension
};

/// Everything a mesh file holds. volume, surface and lines all share the SAME node array
/// (every node of the file, renumbered 0-based dense in file order), so indices agree between
/// them and with the groups.
struct MeshData {
  std::string format;  ///< "msh2.2", "msh4.1", "msh4.1-binary", "vtk", "obj", "stl", ...
  TetMesh volume;      ///< 4-node tetrahedra
  TriMesh surface;     ///< 3-node triangles
  LineMesh lines;      ///< 2-node segments
  /// Per element: the first (file order) physical tag it belongs to, 0 if none.
  std::vector<int> tet_physical, tri_physical, line_physical;
  std::vector<PhysicalGroup> groups;    ///< ordered by (dim, tag)
  std::vector<std::int64_t> node_tags;  ///< original file tag of each node (1-based for OBJ/STL)
  std::vector<std::string> warnings;    ///< non-fatal remarks (dropped degenerate STL facets...)

  /// Number of nodes (columns of the shared node array).
  std::int64_t num_nodes() const { return volume.nodes.cols(); }
};

/// Reads a mesh file, choosing the format by extension (.msh, .vtk, .obj, .stl; case-insensitive).
MeshData ReadMesh(const std::string& path);
/// Reads a file and returns its tetrahedra (all file nodes kept); InputError if it has none.
TetMesh ReadTetMesh(const std::string& path);
/// Reads a file's triangles; for a file without triangles but with tetrahedra, the outward
/// boundary of the tetrahedra (same node indices). InputError if neither exists.
TriMesh ReadTriMesh(const std::string& path);
/// Reads a file's 2-node line elements (all file nodes kept); InputError if it has none.
LineMesh ReadLineMesh(const std::string& path);

/// Parses an in-memory file body; `name` is used for messages and the extension. For tests.
MeshData ParseMesh(const std::string& name, const std::string& bytes);

/// Wraps a TetMesh (and optionally nothing else) into a MeshData, for the writers.
MeshData MakeMeshData(const TetMesh& tets);
/// Wraps a TriMesh into a MeshData, for the writers.
MeshData MakeMeshData(const TriMesh& tris);

/// Writes Gmsh 4.1 ASCII: nodes, tets/tris/lines and physical groups (names kept); exact
/// doubles (17 significant digits). Throws std::runtime_error if the file cannot be written.
void WriteMsh41Ascii(const std::string& path, const MeshData& data);
/// Writes legacy VTK 3.0 ASCII UNSTRUCTURED_GRID with all elements and a cell scalar
/// "physical" holding the per-element physical tag. Exact doubles.
void WriteVtk(const std::string& path, const MeshData& data);
/// Writes Wavefront OBJ: v lines (exact doubles), f lines for triangles, l lines for lines.
void WriteObj(const std::string& path, const MeshData& data);
/// Writes binary STL of the triangles (float32 coordinates, facet normals by right-hand rule).
void WriteStlBinary(const std::string& path, const TriMesh& tris);

}  // namespace arthrosim::mesh
