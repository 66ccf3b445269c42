#include "arthrosim/physics/bone_surface.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <vector>

namespace arthrosim::physics {

namespace {

using mesh::Tri;

double TriVolume(const Points& x, const Tri& t) {
  return x.col(t[0]).dot(x.col(t[1]).cross(x.col(t[2]))) / 6.0;
}

Vec3 TriNormal(const Points& x, const Tri& t) {
  return (x.col(t[1]) - x.col(t[0])).cross(x.col(t[2]) - x.col(t[0]));
}

// A region the tool can reach: a sphere (center, radius) bounding the tool shape or, when `axis`
// is a unit vector, the cylinder of that radius about the line through center along it, between
// axial coordinates axial_lo and axial_hi. In the cylinder case lengths are measured across the
// axis (see PushAlong).
struct Region {
  Vec3 center = Vec3::Zero();
  double radius = 0;
  Vec3 axis = Vec3::Zero();
  double axial_lo = 0, axial_hi = 0;
};

// Whether the axial coordinate of p lies within the cylinder's extent widened by `reach`.
bool WithinAxially(const Region& r, const Vec3& p, double reach) {
  const double s = (p - r.center).dot(r.axis);
  return s >= r.axial_lo - reach && s <= r.axial_hi + reach;
}

// v with its component along the region's axis removed (v itself for a sphere).
Vec3 Across(const Region& r, const Vec3& v) { return v - v.dot(r.axis) * r.axis; }

// Whether segment (a, b) reaches the cylinder's axial extent (always, for a sphere).
bool AxiallyOverlaps(const Region& r, const Vec3& a, const Vec3& b) {
  if (r.axis.squaredNorm() == 0) return true;
  const double sa = (a - r.center).dot(r.axis), sb = (b - r.center).dot(r.axis);
  return std::max(sa, sb) >= r.axial_lo && std::min(sa, sb) <= r.axial_hi;
}

bool InRegion(const Region& r, const Vec3& p) {
  if (r.axis.squaredNorm() == 0) return (p - r.center).norm() <= r.radius;
  return WithinAxially(r, p, 0.0) && Across(r, p - r.center).norm() <= r.radius;
}

double PointSegmentDistance(const Vec3& p, const Vec3& a, const Vec3& b) {
  const Vec3 ab = b - a;
  const double len2 = ab.squaredNorm();
  const double t = len2 > 0 ? std::clamp((p - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
  return (a + t * ab - p).norm();
}

bool TriNearRegion(const Points& x, const Tri& t, const Region& r) {
  if (r.axis.squaredNorm() > 0) {  // bounding sphere of the triangle against the cylinder
    const Vec3 c = (x.col(t[0]) + x.col(t[1]) + x.col(t[2])) / 3.0;
    double reach = 0;
    for (int k = 0; k < 3; ++k) reach = std::max(reach, (x.col(t[k]) - c).norm());
    return WithinAxially(r, c, reach) && Across(r, c - r.center).norm() <= r.radius + reach;
  }
  Vec3 lo = x.col(t[0]), hi = x.col(t[0]);
  for (int k = 1; k < 3; ++k) {
    lo = lo.cwiseMin(x.col(t[k]));
    hi = hi.cwiseMax(x.col(t[k]));
  }
  const Vec3 closest = r.center.cwiseMax(lo).cwiseMin(hi);
  return (closest - r.center).norm() <= r.radius;
}

// A directed edge (a, b) of triangle t, a at local index k.
struct DirectedEdge {
  int a, b, t, k;
};

bool EdgeLess(const DirectedEdge& x, const DirectedEdge& y) {
  return x.a != y.a ? x.a < y.a : x.b < y.b;
}

// The directed edge (a, b) in the sorted list, or nullptr.
const DirectedEdge* FindEdge(const std::vector<DirectedEdge>& sorted, int a, int b) {
  const DirectedEdge key{a, b, 0, 0};
  const auto it = std::lower_bound(sorted.begin(), sorted.end(), key, EdgeLess);
  return it != sorted.end() && it->a == a && it->b == b ? &*it : nullptr;
}

// Whether triangle t is a sliver beside an edge of length edge_mm: its area (across the region's
// axis for a cylinder) below 1e-3 of edge_mm squared.
bool Sliver(const mesh::TriMesh& m, const Region& r, const Tri& t, double edge_mm) {
  const Vec3 u = Across(r, m.nodes.col(t[1]) - m.nodes.col(t[0]));
  const Vec3 v = Across(r, m.nodes.col(t[2]) - m.nodes.col(t[0]));
  return 0.5 * u.cross(v).norm() < 1e-3 * edge_mm * edge_mm;
}

// Splits, longest first, every edge within the region longer than max_edge. Each pass splits an
// independent set of edges (no triangle touched twice), then the adjacency is rebuilt. The
// edges are a sorted vector (binary search) and the pass's midpoints are appended at its end:
// the awl's deep holes split thousands of edges per call, and a node map or one resize per split
// made that minutes.
int SplitLongEdges(mesh::TriMesh* m, const Region& region, double max_edge,
                   std::vector<std::array<int, 2>>* parents) {
  int splits = 0;
  std::vector<DirectedEdge> directed;
  struct Candidate {
    double length;
    int a, b;
  };
  std::vector<Candidate> cand;
  std::vector<Vec3> mids;
  // Each pass at least halves the longest candidate edge or splits an independent set, so the
  // loop ends; the bound only guards against a non-finite input.
  for (int pass = 0; pass < 100000; ++pass) {
    directed.clear();
    for (int t = 0; t < static_cast<int>(m->tris.size()); ++t) {
      if (!TriNearRegion(m->nodes, m->tris[t], region)) continue;
      for (int k = 0; k < 3; ++k)
        directed.push_back({m->tris[t][k], m->tris[t][(k + 1) % 3], t, k});
    }
    std::sort(directed.begin(), directed.end(), EdgeLess);
    cand.clear();
    for (const DirectedEdge& e : directed) {
      if (e.a > e.b) continue;                                // each undirected edge once
      if (FindEdge(directed, e.b, e.a) == nullptr) continue;  // an open edge
      const Vec3 pa = m->nodes.col(e.a), pb = m->nodes.col(e.b);
      const double len = Across(region, pb - pa).norm();
      if (len <= max_edge) continue;
      if (PointSegmentDistance(Vec3::Zero(), Across(region, pa - region.center),
                               Across(region, pb - region.center)) > region.radius)
        continue;
      if (!AxiallyOverlaps(region, pa, pb)) continue;
      // A sliver (opposite vertex on the edge's line, as measured) is left alone: halving its
      // edge makes two slivers with an edge as long, and the passes would never end.
      const DirectedEdge* twin = FindEdge(directed, e.b, e.a);
      if (Sliver(*m, region, m->tris[e.t], len) || Sliver(*m, region, m->tris[twin->t], len))
        continue;
      cand.push_back({len, e.a, e.b});
    }
    if (cand.empty()) break;
    std::sort(cand.begin(), cand.end(), [](const Candidate& x, const Candidate& y) {
      if (x.length != y.length) return x.length > y.length;
      if (x.a != y.a) return x.a < y.a;
      return x.b < y.b;
    });
    std::vector<std::uint8_t> touched(m->tris.size(), 0);
    const int first_mid = static_cast<int>(m->nodes.cols());
    mids.clear();
    for (const Candidate& c : cand) {
      const DirectedEdge& e1 = *FindEdge(directed, c.a, c.b);
      const DirectedEdge& e2 = *FindEdge(directed, c.b, c.a);
      if (touched[e1.t] || touched[e2.t]) continue;
      touched[e1.t] = touched[e2.t] = 1;
      const int mid = first_mid + static_cast<int>(mids.size());
      mids.push_back(0.5 * (m->nodes.col(c.a) + m->nodes.col(c.b)));
      parents->push_back({c.a, c.b});
      // (a, b, c) -> (a, m, c) + (m, b, c); (b, a, d) -> (b, m, d) + (m, a, d).
      const Tri t1 = m->tris[e1.t], t2 = m->tris[e2.t];
      const int opp1 = t1[(e1.k + 2) % 3], opp2 = t2[(e2.k + 2) % 3];
      m->tris[e1.t] = {c.a, mid, opp1};
      m->tris.push_back({mid, c.b, opp1});
      m->tris[e2.t] = {c.b, mid, opp2};
      m->tris.push_back({mid, c.a, opp2});
      touched.push_back(1);
      touched.push_back(1);
      ++splits;
    }
    m->nodes.conservativeResize(3, first_mid + static_cast<int>(mids.size()));
    for (std::size_t i = 0; i < mids.size(); ++i)
      m->nodes.col(first_mid + static_cast<int>(i)) = mids[i];
  }
  return splits;
}

// One tool operation: `target(p, &q)` returns true and the destination q for a vertex inside
// the tool. Vertices move toward q by at most max_move. `view(p)` is the direction from p to the
// tool (the projection direction): a move is kept only if every incident triangle still faces
// the tool the way it did (sign of normal . view), i.e. no triangle folds over as seen along the
// projection. Comparing with the old normal instead would reject the legitimate >90 degree
// turns of a surface wrapping onto the burr.
double Reshape(BoneState* bone, const Region& region, double max_move,
               const std::function<bool(const Vec3&, Vec3*)>& target,
               const std::function<Vec3(const Vec3&)>& view, const BoneCarveOptions& opt) {
  mesh::TriMesh& m = bone->surface;
  const double v_before = EnclosedVolume(m);
  std::vector<double> moved_total;
  bool changed = false;  // any split or kept move: the surface's revision goes up
  for (int round = 0; round < opt.rounds; ++round) {
    const int n_before = static_cast<int>(m.nodes.cols());
    std::vector<std::array<int, 2>> parents;
    SplitLongEdges(&m, region, opt.max_edge_mm, &parents);
    const int n = static_cast<int>(m.nodes.cols());
    changed = changed || n > n_before;
    // A midpoint already sits where its parents were moved: it inherits their used depth, so no
    // point of the surface moves more than max_move in one call.
    moved_total.resize(n, 0.0);
    for (int i = n_before; i < n; ++i) {
      const std::array<int, 2>& pr = parents[i - n_before];
      moved_total[i] = std::max(moved_total[pr[0]], moved_total[pr[1]]);
    }
    const Points old = m.nodes;
    std::vector<std::uint8_t> moved(n, 0);
    bool any = false;
    for (int i = 0; i < n; ++i) {
      if (!InRegion(region, old.col(i))) continue;
      Vec3 q;
      if (!target(old.col(i), &q)) continue;
      const Vec3 d = q - old.col(i);
      const double len = d.norm();
      const double budget = max_move - moved_total[i];
      if (len <= 1e-12 || budget <= 1e-12) continue;
      m.nodes.col(i) = old.col(i) + d * std::min(1.0, budget / len);
      moved[i] = 1;
      any = true;
    }
    if (!any) break;
    // Revert vertices whose move flips an incident triangle; repeat until none flips.
    std::vector<int> tris;
    for (int t = 0; t < static_cast<int>(m.tris.size()); ++t) {
      const Tri& tr = m.tris[t];
      if (moved[tr[0]] || moved[tr[1]] || moved[tr[2]]) tris.push_back(t);
    }
    for (int pass = 0; pass < 32; ++pass) {
      bool reverted = false;
      for (int t : tris) {
        const Tri& tr = m.tris[t];
        const Vec3 c0 = (old.col(tr[0]) + old.col(tr[1]) + old.col(tr[2])) / 3.0;
        const Vec3 c1 = (m.nodes.col(tr[0]) + m.nodes.col(tr[1]) + m.nodes.col(tr[2])) / 3.0;
        const double f0 = TriNormal(old, tr).dot(view(c0));
        const double f1 = TriNormal(m.nodes, tr).dot(view(c1));
        if ((f0 > 0) == (f1 > 0) && f1 != 0) continue;
        for (int k = 0; k < 3; ++k) {
          if (!moved[tr[k]]) continue;
          m.nodes.col(tr[k]) = old.col(tr[k]);
          moved[tr[k]] = 0;
          reverted = true;
        }
      }
      if (!reverted) break;
    }
    for (int i = 0; i < n; ++i) {
      if (moved[i]) moved_total[i] += (m.nodes.col(i) - old.col(i)).norm();
      changed = changed || moved[i];
    }
  }
  if (changed) ++bone->revision;
  const double removed = v_before - EnclosedVolume(m);
  bone->removed_volume_mm3 += removed;
  return removed;
}

}  // namespace

double EnclosedVolume(const mesh::TriMesh& surface) {
  double v = 0;
  for (const Tri& t : surface.tris) v += TriVolume(surface.nodes, t);
  return v;
}

WatertightReport CheckWatertight(const mesh::TriMesh& surface) {
  WatertightReport r;
  const int n = static_cast<int>(surface.nodes.cols());
  std::vector<std::array<int, 2>> edges;
  edges.reserve(3 * surface.tris.size());
  for (const Tri& t : surface.tris) {
    bool bad = false;
    for (int k = 0; k < 3; ++k) bad |= t[k] < 0 || t[k] >= n;
    bad |= t[0] == t[1] || t[1] == t[2] || t[0] == t[2];
    if (bad) {
      ++r.degenerate_tris;
      continue;
    }
    for (int k = 0; k < 3; ++k) edges.push_back({t[k], t[(k + 1) % 3]});
  }
  std::sort(edges.begin(), edges.end());
  for (std::size_t i = 0; i < edges.size(); ++i) {
    if (i > 0 && edges[i] == edges[i - 1]) {
      ++r.nonmanifold_edges;
      continue;
    }
    if (!std::binary_search(edges.begin(), edges.end(),
                            std::array<int, 2>{edges[i][1], edges[i][0]}))
      ++r.boundary_edges;
  }
  return r;
}

double CarveSphere(BoneState* bone, const Vec3& center, double radius_mm, double max_depth_mm,
                   const BoneCarveOptions& options) {
  if (!(radius_mm > 0) || !(max_depth_mm > 0)) return 0.0;
  const Region region{center, radius_mm + options.max_edge_mm};
  auto target = [&](const Vec3& p, Vec3* q) {
    const Vec3 d = p - center;
    const double r = d.norm();
    if (r >= radius_mm || r < 1e-12) return false;
    *q = center + d * (radius_mm / r);
    return true;
  };
  auto view = [&](const Vec3& p) { return Vec3(center - p); };
  return Reshape(bone, region, max_depth_mm, target, view, options);
}

double SmoothRim(BoneState* bone, const Vec3& center, double inner_mm, double outer_mm,
                 int iterations) {
  if (!(outer_mm > inner_mm) || iterations <= 0) return 0.0;
  mesh::TriMesh& m = bone->surface;
  const int n = static_cast<int>(m.nodes.cols());
  auto in_band = [&](const Vec3& p) {
    const double d = (p - center).norm();
    return d >= inner_mm && d <= outer_mm;
  };
  // Triangles touching the band, and the ring neighbours of each band vertex (sorted, unique).
  const Region region{center, outer_mm};
  std::vector<int> tris;
  std::vector<std::vector<int>> nbr(static_cast<std::size_t>(n));
  std::vector<std::vector<int>> vtris(static_cast<std::size_t>(n));
  for (int t = 0; t < static_cast<int>(m.tris.size()); ++t) {
    if (!TriNearRegion(m.nodes, m.tris[t], region)) continue;
    tris.push_back(t);
    for (int k = 0; k < 3; ++k) {
      const int a = m.tris[t][k];
      vtris[a].push_back(t);
      nbr[a].push_back(m.tris[t][(k + 1) % 3]);
      nbr[a].push_back(m.tris[t][(k + 2) % 3]);
    }
  }
  const double v_before = EnclosedVolume(m);
  bool changed = false;
  for (int it = 0; it < iterations; ++it) {
    const Points old = m.nodes;
    for (int i = 0; i < n; ++i) {
      if (nbr[i].empty() || !in_band(old.col(i))) continue;
      std::vector<int>& ring = nbr[i];
      std::sort(ring.begin(), ring.end());
      ring.erase(std::unique(ring.begin(), ring.end()), ring.end());
      Vec3 mean = Vec3::Zero();
      for (int j : ring) mean += old.col(j);
      mean /= static_cast<double>(ring.size());
      Vec3 normal = Vec3::Zero();
      for (int t : vtris[i]) normal += TriNormal(old, m.tris[t]);
      const Vec3 d = 0.5 * (mean - old.col(i));
      if (!(normal.dot(d) < 0)) continue;  // outward or tangential: would add or only slide
      m.nodes.col(i) = old.col(i) + d;
      // Keep the move only if no incident triangle turns over.
      bool flips = false;
      for (int t : vtris[i]) {
        const double before = TriNormal(old, m.tris[t]).dot(TriNormal(m.nodes, m.tris[t]));
        flips = flips || !(before > 0);
      }
      if (flips) {
        m.nodes.col(i) = old.col(i);
      } else {
        changed = true;
      }
    }
  }
  if (changed) ++bone->revision;
  const double removed = v_before - EnclosedVolume(m);
  bone->removed_volume_mm3 += removed;
  return removed;
}

double PushAlong(BoneState* bone, const Vec3& tip, const Vec3& axis, double radius_mm,
                 double depth_mm, const BoneCarveOptions& options) {
  if (!(radius_mm > 0) || !(depth_mm > 0) || !(axis.norm() > 0)) return 0.0;
  const Vec3 u = axis.normalized();
  // Vertices move along u only, so the mesh is refined across u alone (edge lengths projected
  // on the plane normal to u): once the disc under the awl is refined, deepening the hole splits
  // nothing more. Refining in 3-D re-split the stretched hole wall at every deeper push and
  // grew slivers without bound (25 000 triangles and seconds per step for a 6 mm hole).
  const Region region{tip, radius_mm + options.max_edge_mm, u, -radius_mm, depth_mm};
  auto target = [&](const Vec3& p, Vec3* q) {
    const Vec3 d = p - tip;
    const double s = d.dot(u);
    const double rho = (d - s * u).norm();
    if (rho >= radius_mm || s < -radius_mm) return false;
    const double f = depth_mm * (1 - (rho / radius_mm) * (rho / radius_mm));
    if (s >= f) return false;
    *q = p + (f - s) * u;
    return true;
  };
  auto view = [&](const Vec3&) { return Vec3(-u); };
  return Reshape(bone, region, depth_mm + radius_mm, target, view, options);
}

}  // namespace arthrosim::physics
