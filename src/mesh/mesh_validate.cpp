#include "arthrosim/mesh/mesh_validate.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>
#include <utility>

#include "arthrosim/core/error.h"

namespace arthrosim::mesh {
namespace {

void CheckNodesFinite(const Points& p, const std::string& file) {
  for (Eigen::Index i = 0; i < p.cols(); ++i) {
    if (!p.col(i).allFinite()) {
      throw InputError(file, 0, "node " + std::to_string(i),
                       "non-finite coordinate; expected finite millimetres");
    }
  }
}

/// Checks index range and repeats for one element; marks used nodes.
template <std::size_t K>
void CheckElement(const std::array<std::int32_t, K>& e, std::size_t index, Eigen::Index n,
                  const char* kind, const std::string& file, std::vector<std::uint8_t>* used) {
  for (std::size_t k = 0; k < K; ++k) {
    if (e[k] < 0 || e[k] >= n) {
      throw InputError(
          file, 0, std::string(kind) + " " + std::to_string(index),
          "node index " + std::to_string(e[k]) + " out of range [0, " + std::to_string(n) + ")");
    }
    for (std::size_t j = 0; j < k; ++j) {
      if (e[j] == e[k]) {
        throw InputError(file, 0, std::string(kind) + " " + std::to_string(index),
                         "node " + std::to_string(e[k]) + " appears twice; expected " +
                             std::to_string(K) + " distinct nodes");
      }
    }
    (*used)[static_cast<std::size_t>(e[k])] = 1;
  }
}

std::int64_t CountUnused(const std::vector<std::uint8_t>& used) {
  return std::count(used.begin(), used.end(), std::uint8_t{0});
}

}  // namespace

double TetSignedVolume(const Points& p, const Tet& t) {
  const Vec3 a = p.col(t[0]);
  return (p.col(t[1]) - a).dot((p.col(t[2]) - a).cross(p.col(t[3]) - a)) / 6.0;
}

double TotalVolume(const TetMesh& m) {
  double v = 0;
  for (const Tet& t : m.tets) v += TetSignedVolume(m.nodes, t);
  return v;
}

double EnclosedVolume(const TriMesh& m) {
  if (m.tris.empty()) return 0.0;
  // Any reference point gives the same result for a closed surface; one on the surface keeps
  // the terms small (less cancellation far from the origin).
  const Vec3 c = m.nodes.col(m.tris.front()[0]);
  double v = 0;
  for (const Tri& t : m.tris) {
    const Vec3 a = m.nodes.col(t[0]) - c, b = m.nodes.col(t[1]) - c, d = m.nodes.col(t[2]) - c;
    v += a.dot(b.cross(d));
  }
  return v / 6.0;
}

TetQualityReport OrientAndCheck(TetMesh* m, const std::string& file) {
  TetQualityReport r;
  CheckNodesFinite(m->nodes, file);
  std::vector<std::uint8_t> used(static_cast<std::size_t>(m->nodes.cols()), 0);
  r.num_tets = static_cast<std::int64_t>(m->tets.size());
  bool first = true;
  for (std::size_t i = 0; i < m->tets.size(); ++i) {
    Tet& t = m->tets[i];
    CheckElement(t, i, m->nodes.cols(), "tet", file, &used);
    double longest2 = 0;
    for (int a = 0; a < 4; ++a) {
      for (int b = a + 1; b < 4; ++b) {
        longest2 = std::max(longest2, (m->nodes.col(t[a]) - m->nodes.col(t[b])).squaredNorm());
      }
    }
    const double l = std::sqrt(longest2);
    double v = TetSignedVolume(m->nodes, t);
    if (std::abs(6.0 * v) <= kDegenerateTol * l * l * l) {
      r.degenerate.push_back(static_cast<std::int32_t>(i));
    } else if (v < 0) {
      std::swap(t[2], t[3]);
      v = -v;
      ++r.num_reoriented;
    }
    r.min_volume = first ? v : std::min(r.min_volume, v);
    r.max_volume = first ? v : std::max(r.max_volume, v);
    r.total_volume += v;
    first = false;
  }
  r.num_unreferenced_nodes = CountUnused(used);
  return r;
}

TriQualityReport OrientAndCheck(TriMesh* m, const std::string& file) {
  TriQualityReport r;
  CheckNodesFinite(m->nodes, file);
  std::vector<std::uint8_t> used(static_cast<std::size_t>(m->nodes.cols()), 0);
  r.num_tris = static_cast<std::int64_t>(m->tris.size());
  // Directed edges (min, max, forward?) to test closedness and orientation consistency.
  std::vector<std::array<std::int32_t, 3>> edges;
  edges.reserve(m->tris.size() * 3);
  for (std::size_t i = 0; i < m->tris.size(); ++i) {
    const Tri& t = m->tris[i];
    CheckElement(t, i, m->nodes.cols(), "triangle", file, &used);
    const Vec3 a = m->nodes.col(t[0]), b = m->nodes.col(t[1]), c = m->nodes.col(t[2]);
    const double l2 =
        std::max({(b - a).squaredNorm(), (c - b).squaredNorm(), (a - c).squaredNorm()});
    const double twice_area = (b - a).cross(c - a).norm();
    if (twice_area <= kDegenerateTol * l2) r.degenerate.push_back(static_cast<std::int32_t>(i));
    r.area += 0.5 * twice_area;
    for (int k = 0; k < 3; ++k) {
      const std::int32_t u = t[k], v = t[(k + 1) % 3];
      edges.push_back({std::min(u, v), std::max(u, v), u < v ? 1 : 0});
    }
  }
  std::sort(edges.begin(), edges.end());
  r.closed = !m->tris.empty();
  r.consistently_oriented = true;
  for (std::size_t i = 0; i < edges.size();) {
    std::size_t j = i + 1;
    while (j < edges.size() && edges[j][0] == edges[i][0] && edges[j][1] == edges[i][1]) ++j;
    if (j - i != 2) {
      r.closed = false;
      if (j - i > 2) r.consistently_oriented = false;
    } else if (edges[i][2] == edges[i + 1][2]) {
      r.consistently_oriented = false;
    }
    i = j;
  }
  r.enclosed_volume = EnclosedVolume(*m);
  if (r.closed && r.consistently_oriented && r.enclosed_volume < 0) {
    for (Tri& t : m->tris) std::swap(t[1], t[2]);
    r.enclosed_volume = -r.enclosed_volume;
    r.flipped = true;
  }
  r.num_unreferenced_nodes = CountUnused(used);
  return r;
}

std::vector<std::int32_t> RemoveUnreferencedNodes(TetMesh* m) {
  const auto n = static_cast<std::size_t>(m->nodes.cols());
  std::vector<std::int32_t> map(n, -1);
  for (const Tet& t : m->tets) {
    for (const std::int32_t v : t) {
      if (v < 0 || static_cast<std::size_t>(v) >= n) {
        throw std::out_of_range("RemoveUnreferencedNodes: node index " + std::to_string(v) +
                                " out of range (run OrientAndCheck first)");
      }
      map[static_cast<std::size_t>(v)] = 0;
    }
  }
  std::int32_t next = 0;
  for (std::int32_t& v : map) {
    if (v == 0) v = next++;
  }
  Points kept(3, next);
  for (std::size_t i = 0; i < n; ++i) {
    if (map[i] >= 0) kept.col(map[i]) = m->nodes.col(static_cast<Eigen::Index>(i));
  }
  m->nodes = std::move(kept);
  for (Tet& t : m->tets) {
    for (std::int32_t& v : t) v = map[static_cast<std::size_t>(v)];
  }
  return map;
}

}  // namespace arthrosim::mesh
