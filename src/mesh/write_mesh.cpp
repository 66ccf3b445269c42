// Debug writers. Doubles are written in the shortest form that reads back bit-identical.
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

#include "arthrosim/mesh/mesh_io.h"

namespace arthrosim::mesh {
namespace {

void Num(std::string* out, double v) {
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof(buf), v);
  out->append(buf, r.ptr);
}

void Save(const std::string& path, const std::string& body) {
  std::ofstream f(path, std::ios::binary);
  if (!f) throw std::runtime_error(path + ": cannot open for writing");
  f.write(body.data(), static_cast<std::streamsize>(body.size()));
  if (!f) throw std::runtime_error(path + ": write failed");
}

const Points& SharedNodes(const MeshData& d) {
  // The three containers share one node array; any non-empty one is it.
  if (d.volume.nodes.cols() > 0) return d.volume.nodes;
  if (d.surface.nodes.cols() > 0) return d.surface.nodes;
  return d.lines.nodes;
}

void AppendNodes(std::string* s, const Points& p, const char* prefix) {
  for (Eigen::Index i = 0; i < p.cols(); ++i) {
    *s += prefix;
    for (int k = 0; k < 3; ++k) {
      if (k > 0) *s += ' ';
      Num(s, p(k, i));
    }
    *s += '\n';
  }
}

}  // namespace

void WriteMsh41Ascii(const std::string& path, const MeshData& d) {
  const Points& p = SharedNodes(d);
  const std::size_t counts[4] = {0, d.lines.edges.size(), d.surface.tris.size(),
                                 d.volume.tets.size()};
  // Entities = distinct physical memberships per dimension, numbered by first appearance.
  std::vector<std::vector<std::vector<int>>> member(4);
  for (int dim = 1; dim <= 3; ++dim) member[dim].resize(counts[dim]);
  for (const PhysicalGroup& g : d.groups) {
    if (g.dim < 1 || g.dim > 3) continue;
    for (const std::int32_t e : g.elements) {
      if (e >= 0 && static_cast<std::size_t>(e) < counts[g.dim]) member[g.dim][e].push_back(g.tag);
    }
  }
  std::vector<std::map<std::vector<int>, int>> entity(4);
  std::vector<std::vector<std::vector<int>>> entity_phys(4);
  std::vector<std::vector<int>> elem_entity(4);
  for (int dim = 1; dim <= 3; ++dim) {
    for (std::size_t e = 0; e < counts[dim]; ++e) {
      const auto [it, fresh] =
          entity[dim].emplace(member[dim][e], static_cast<int>(entity[dim].size()) + 1);
      if (fresh) entity_phys[dim].push_back(member[dim][e]);
      elem_entity[dim].push_back(it->second);
    }
  }
  int node_dim = 3;
  while (node_dim > 0 && entity_phys[node_dim].empty()) --node_dim;
  if (node_dim == 0) entity_phys[3].push_back({}), node_dim = 3;  // a host for the nodes

  Eigen::Vector3d lo = Eigen::Vector3d::Zero(), hi = Eigen::Vector3d::Zero();
  if (p.cols() > 0) {
    lo = p.rowwise().minCoeff();
    hi = p.rowwise().maxCoeff();
  }
  std::string s = "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n";
  int named = 0;
  for (const PhysicalGroup& g : d.groups) named += g.name.empty() ? 0 : 1;
  if (named > 0) {
    s += "$PhysicalNames\n" + std::to_string(named) + "\n";
    for (const PhysicalGroup& g : d.groups) {
      if (!g.name.empty()) {
        s += std::to_string(g.dim) + " " + std::to_string(g.tag) + " \"" + g.name + "\"\n";
      }
    }
    s += "$EndPhysicalNames\n";
  }
  s += "$Entities\n0 " + std::to_string(entity_phys[1].size()) + " " +
       std::to_string(entity_phys[2].size()) + " " + std::to_string(entity_phys[3].size()) + "\n";
  for (int dim = 1; dim <= 3; ++dim) {
    for (std::size_t e = 0; e < entity_phys[dim].size(); ++e) {
      s += std::to_string(e + 1);
      for (int k = 0; k < 3; ++k) s += ' ', Num(&s, lo[k]);
      for (int k = 0; k < 3; ++k) s += ' ', Num(&s, hi[k]);
      s += ' ' + std::to_string(entity_phys[dim][e].size());
      for (const int t : entity_phys[dim][e]) s += ' ' + std::to_string(t);
      s += " 0\n";
    }
  }
  s += "$EndEntities\n$Nodes\n";
  const std::string n = std::to_string(p.cols());
  if (p.cols() == 0) {
    s += "0 0 0 0\n";
  } else {
    s += "1 " + n + " 1 " + n + "\n" + std::to_string(node_dim) + " 1 0 " + n + "\n";
    for (Eigen::Index i = 0; i < p.cols(); ++i) s += std::to_string(i + 1) + "\n";
    AppendNodes(&s, p, "");
  }
  s += "$EndNodes\n$Elements\n";
  // Blocks: runs of consecutive elements with the same entity, lines then triangles then tets,
  // so per-dimension element order is preserved.
  std::string body;
  std::size_t nblocks = 0, tag = 0;
  const int gmsh_type[4] = {15, 1, 2, 4};
  for (int dim = 1; dim <= 3; ++dim) {
    for (std::size_t e = 0; e < counts[dim];) {
      std::size_t f = e + 1;
      while (f < counts[dim] && elem_entity[dim][f] == elem_entity[dim][e]) ++f;
      body += std::to_string(dim) + " " + std::to_string(elem_entity[dim][e]) + " " +
              std::to_string(gmsh_type[dim]) + " " + std::to_string(f - e) + "\n";
      for (std::size_t i = e; i < f; ++i) {
        body += std::to_string(++tag);
        for (int k = 0; k <= dim; ++k) {
          const std::int32_t v = dim == 3   ? d.volume.tets[i][k]
                                 : dim == 2 ? d.surface.tris[i][k]
                                            : d.lines.edges[i][k];
          body += ' ' + std::to_string(v + 1);
        }
        body += '\n';
      }
      ++nblocks;
      e = f;
    }
  }
  s += std::to_string(nblocks) + " " + std::to_string(tag) + " " + (tag ? "1" : "0") + " " +
       std::to_string(tag) + "\n" + body + "$EndElements\n";
  Save(path, s);
}

void WriteVtk(const std::string& path, const MeshData& d) {
  const Points& p = SharedNodes(d);
  std::string s = "# vtk DataFile Version 3.0\narthrosim mesh\nASCII\nDATASET UNSTRUCTURED_GRID\n";
  s += "POINTS " + std::to_string(p.cols()) + " double\n";
  AppendNodes(&s, p, "");
  const std::size_t ncell = d.volume.tets.size() + d.surface.tris.size() + d.lines.edges.size();
  const std::size_t size =
      5 * d.volume.tets.size() + 4 * d.surface.tris.size() + 3 * d.lines.edges.size();
  s += "CELLS " + std::to_string(ncell) + " " + std::to_string(size) + "\n";
  auto cell = [&s](const std::int32_t* v, int k) {
    s += std::to_string(k);
    for (int i = 0; i < k; ++i) s += ' ' + std::to_string(v[i]);
    s += '\n';
  };
  for (const Tet& t : d.volume.tets) cell(t.data(), 4);
  for (const Tri& t : d.surface.tris) cell(t.data(), 3);
  for (const Edge& e : d.lines.edges) cell(e.data(), 2);
  s += "CELL_TYPES " + std::to_string(ncell) + "\n";
  for (std::size_t i = 0; i < d.volume.tets.size(); ++i) s += "10\n";
  for (std::size_t i = 0; i < d.surface.tris.size(); ++i) s += "5\n";
  for (std::size_t i = 0; i < d.lines.edges.size(); ++i) s += "3\n";
  s += "CELL_DATA " + std::to_string(ncell) + "\nSCALARS physical int 1\nLOOKUP_TABLE default\n";
  auto phys = [&s](const std::vector<int>& v, std::size_t n) {
    for (std::size_t i = 0; i < n; ++i) s += std::to_string(i < v.size() ? v[i] : 0) + "\n";
  };
  phys(d.tet_physical, d.volume.tets.size());
  phys(d.tri_physical, d.surface.tris.size());
  phys(d.line_physical, d.lines.edges.size());
  Save(path, s);
}

void WriteObj(const std::string& path, const MeshData& d) {
  const Points& p = SharedNodes(d);
  std::string s = "# arthrosim mesh\n";
  AppendNodes(&s, p, "v ");
  for (const Tri& t : d.surface.tris) {
    s += "f " + std::to_string(t[0] + 1) + " " + std::to_string(t[1] + 1) + " " +
         std::to_string(t[2] + 1) + "\n";
  }
  for (const Edge& e : d.lines.edges) {
    s += "l " + std::to_string(e[0] + 1) + " " + std::to_string(e[1] + 1) + "\n";
  }
  Save(path, s);
}

void WriteStlBinary(const std::string& path, const TriMesh& m) {
  std::string s(80, '\0');
  const char kHeader[] = "arthrosim binary STL";
  std::memcpy(s.data(), kHeader, sizeof(kHeader) - 1);
  auto put = [&s](const void* v, std::size_t n) { s.append(static_cast<const char*>(v), n); };
  const auto n = static_cast<std::uint32_t>(m.tris.size());
  put(&n, 4);
  for (const Tri& t : m.tris) {
    const Vec3 a = m.nodes.col(t[0]), b = m.nodes.col(t[1]), c = m.nodes.col(t[2]);
    Vec3 nrm = (b - a).cross(c - a);
    const double len = nrm.norm();
    nrm = len > 0 ? Vec3(nrm / len) : Vec3::Zero();
    float f[12];
    for (int k = 0; k < 3; ++k) {
      f[k] = static_cast<float>(nrm[k]);
      f[3 + k] = static_cast<float>(a[k]);
      f[6 + k] = static_cast<float>(b[k]);
      f[9 + k] = static_cast<float>(c[k]);
    }
    put(f, sizeof(f));
    const std::uint16_t attr = 0;
    put(&attr, 2);
  }
  Save(path, s);
}

}  // namespace arthrosim::mesh
