#include "arthrosim/mesh/mesh_summary.h"

#include <cstdio>

#include "arthrosim/mesh/mesh_validate.h"
#include "arthrosim/mesh/surface.h"

namespace arthrosim::mesh {

MeshSummary Summarize(const MeshData& d) {
  MeshSummary s;
  s.format = d.format;
  s.num_nodes = d.num_nodes();
  s.num_tets = static_cast<std::int64_t>(d.volume.tets.size());
  s.num_tris = static_cast<std::int64_t>(d.surface.tris.size());
  s.num_lines = static_cast<std::int64_t>(d.lines.edges.size());
  const Points& p = d.volume.nodes.cols() > 0    ? d.volume.nodes
                    : d.surface.nodes.cols() > 0 ? d.surface.nodes
                                                 : d.lines.nodes;
  if (p.cols() > 0) {
    s.bbox_min_mm = p.rowwise().minCoeff();
    s.bbox_max_mm = p.rowwise().maxCoeff();
  }
  for (const Tet& t : d.volume.tets) {
    const double v = TetSignedVolume(d.volume.nodes, t);
    s.tet_volume_mm3 += v;
    if (v < 0) ++s.num_inverted_tets;
  }
  if (!d.volume.tets.empty()) {
    s.num_boundary_faces = static_cast<std::int64_t>(ExtractBoundary(d.volume.tets).size());
  }
  for (const PhysicalGroup& g : d.groups) {
    s.groups.push_back({g.dim, g.tag, g.name, static_cast<std::int64_t>(g.elements.size())});
  }
  s.warnings = d.warnings;
  return s;
}

std::string FormatSummary(const MeshSummary& s) {
  char buf[256];
  std::string out = "format: " + s.format + "\n";
  out += "nodes: " + std::to_string(s.num_nodes) + "\n";
  out += "tetrahedra: " + std::to_string(s.num_tets) + "\n";
  out += "triangles: " + std::to_string(s.num_tris) + "\n";
  out += "lines: " + std::to_string(s.num_lines) + "\n";
  std::snprintf(buf, sizeof(buf), "bbox_mm: [%.6g, %.6g, %.6g] .. [%.6g, %.6g, %.6g]\n",
                s.bbox_min_mm.x(), s.bbox_min_mm.y(), s.bbox_min_mm.z(), s.bbox_max_mm.x(),
                s.bbox_max_mm.y(), s.bbox_max_mm.z());
  out += buf;
  if (s.num_tets > 0) {
    std::snprintf(buf, sizeof(buf), "tet_volume_mm3: %.9g\n", s.tet_volume_mm3);
    out += buf;
    out += "inverted_tets: " + std::to_string(s.num_inverted_tets) + "\n";
    out += "boundary_faces: " + std::to_string(s.num_boundary_faces) + "\n";
  }
  for (const GroupSummary& g : s.groups) {
    out += "group: dim " + std::to_string(g.dim) + " tag " + std::to_string(g.tag) + " \"" +
           g.name + "\" elements " + std::to_string(g.num_elements) + "\n";
  }
  for (const std::string& w : s.warnings) out += "warning: " + w + "\n";
  return out;
}

}  // namespace arthrosim::mesh
