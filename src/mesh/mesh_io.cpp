// Format dispatch and the convenience readers.
#include "arthrosim/mesh/mesh_io.h"

#include "arthrosim/mesh/surface.h"
#include "cursor.h"
#include "mesh_builder.h"

namespace arthrosim::mesh {

MeshData ParseMesh(const std::string& name, const std::string& bytes) {
  const std::string ext = detail::LowerExtension(name);
  detail::Cursor cur(name, bytes);
  if (ext == "msh") return detail::ReadMsh(cur);
  if (ext == "vtk") return detail::ReadVtk(cur);
  if (ext == "obj") return detail::ReadObj(cur);
  if (ext == "stl") return detail::ReadStl(cur);
  throw InputError(name, 0, "extension",
                   "unknown mesh file extension '" + ext + "' (expected .msh, .vtk, .obj or .stl)");
}

MeshData ReadMesh(const std::string& path) {
  const std::string ext = detail::LowerExtension(path);
  if (ext != "msh" && ext != "vtk" && ext != "obj" && ext != "stl") {
    return ParseMesh(path, std::string());  // throws the unknown-extension error
  }
  return ParseMesh(path, detail::ReadFileBytes(path));
}

TetMesh ReadTetMesh(const std::string& path) {
  MeshData d = ReadMesh(path);
  if (d.volume.tets.empty()) {
    throw InputError(path, 0, "tetrahedra",
                     "expected a volume mesh but the file has no tetrahedra");
  }
  return std::move(d.volume);
}

TriMesh ReadTriMesh(const std::string& path) {
  MeshData d = ReadMesh(path);
  if (!d.surface.tris.empty()) return std::move(d.surface);
  if (!d.volume.tets.empty()) return BoundaryTriMesh(d.volume);
  throw InputError(path, 0, "triangles",
                   "expected a surface mesh but the file has neither triangles nor tetrahedra");
}

LineMesh ReadLineMesh(const std::string& path) {
  MeshData d = ReadMesh(path);
  if (d.lines.edges.empty()) {
    throw InputError(path, 0, "lines", "expected a line mesh but the file has no 2-node lines");
  }
  return std::move(d.lines);
}

namespace {

// A MeshData over `nodes` with no elements yet: format "memory", node tags 1..n in order.
template <class Nodes>
MeshData EmptyMemoryMesh(const Nodes& nodes) {
  MeshData d;
  d.format = "memory";
  d.volume.nodes = nodes;
  d.surface.nodes = nodes;
  d.lines.nodes = nodes;
  d.node_tags.resize(static_cast<std::size_t>(nodes.cols()));
  for (std::size_t i = 0; i < d.node_tags.size(); ++i)
    d.node_tags[i] = static_cast<std::int64_t>(i) + 1;
  return d;
}

}  // namespace

MeshData MakeMeshData(const TetMesh& tets) {
  MeshData d = EmptyMemoryMesh(tets.nodes);
  d.volume = tets;
  d.tet_physical.assign(tets.tets.size(), 0);
  return d;
}

MeshData MakeMeshData(const TriMesh& tris) {
  MeshData d = EmptyMemoryMesh(tris.nodes);
  d.surface = tris;
  d.tri_physical.assign(tris.tris.size(), 0);
  return d;
}

}  // namespace arthrosim::mesh
