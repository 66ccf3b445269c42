// Split-mode scissors cut: tets cut along the blade plane by conforming edge bisection, the two
// sides separated by duplicated nodes on the cut surface.
#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "arthrosim/instruments/cutting.h"

namespace arthrosim::instruments {
namespace {

constexpr int kEdges[6][2] = {{0, 1}, {0, 2}, {0, 3}, {1, 2}, {1, 3}, {2, 3}};

struct CutEdge {
  std::int32_t a = -1, b = -1;  // a < b
  double t = 0;                 // point = (1 - t) x_a + t x_b
  bool operator<(const CutEdge& o) const { return a != o.a ? a < o.a : b < o.b; }
};

// A piece of a split tet: four node ids (new edge points are encoded as -1 - k for cut edge k
// until the nodes exist), and whether it descends from a tet the blade crossed.
struct Piece {
  std::array<std::int64_t, 4> v{};
  bool crossed = false;
};

double SignedVolume(const Vec3& p0, const Vec3& p1, const Vec3& p2, const Vec3& p3) {
  return (p1 - p0).dot((p2 - p0).cross(p3 - p0)) / 6.0;
}

}  // namespace

double RadiusRatio(const Vec3& p0, const Vec3& p1, const Vec3& p2, const Vec3& p3) {
  const double v = SignedVolume(p0, p1, p2, p3);
  const double area = 0.5 * ((p1 - p0).cross(p2 - p0).norm() + (p1 - p0).cross(p3 - p0).norm() +
                             (p2 - p0).cross(p3 - p0).norm() + (p2 - p1).cross(p3 - p1).norm());
  if (area <= 0) return 0;
  const double inradius = 3.0 * std::abs(v) / area;
  // Circumradius: |a^2 (b x c) + b^2 (c x a) + c^2 (a x b)| / (12 |V|) with edges from p0.
  const Vec3 a = p1 - p0, b = p2 - p0, c = p3 - p0;
  const Vec3 num =
      a.squaredNorm() * b.cross(c) + b.squaredNorm() * c.cross(a) + c.squaredNorm() * a.cross(b);
  if (v == 0) return 0;
  const double circumradius = num.norm() / (12.0 * std::abs(v));
  const double q = 3.0 * inradius / circumradius;
  return v > 0 ? q : -q;
}

SplitResult SplitTetsByPlane(const Model& model, int body, std::span<const std::int32_t> tets,
                             const Vec3& point, const Vec3& normal, double snap_fraction,
                             collision::TetTree* tree, physics::SoftSystem* soft, State* state) {
  SplitResult result;
  if (!(snap_fraction >= 0 && snap_fraction < 0.5)) {
    throw std::invalid_argument("SplitTetsByPlane: snap_fraction must be in [0, 0.5)");
  }
  SoftBodyState& sb = state->soft_bodies[static_cast<std::size_t>(body)];
  auto dist = [&](std::int32_t n) { return normal.dot(Vec3(sb.x.col(n)) - point); };
  // Nodes made by earlier splits lie on an earlier cut surface: an edge from one is never cut
  // again and they are never duplicated again (a later cut passes through them), so cutting
  // near an existing cut does not refine it step after step.
  const auto first_made = static_cast<std::int32_t>(
      model.soft_bodies[static_cast<std::size_t>(body)].rest_mesh.nodes.cols());
  // 1. Cut edges of the crossed tets: endpoints strictly on opposite sides and the crossing
  // farther than snap_fraction of the edge from both ends (nearer: the cut passes through the
  // node, which is duplicated below instead of making a sliver).
  std::vector<CutEdge> cuts;
  for (std::int32_t t : tets) {
    const mesh::Tet& e = sb.tets[static_cast<std::size_t>(t)];
    for (const auto& k : kEdges) {
      std::int32_t a = e[k[0]], b = e[k[1]];
      if (a > b) std::swap(a, b);
      if (b >= first_made) continue;
      const double da = dist(a), db = dist(b);
      if (!((da < 0 && db > 0) || (da > 0 && db < 0))) continue;
      const double u = da / (da - db);
      if (u < snap_fraction || u > 1.0 - snap_fraction) continue;
      cuts.push_back(CutEdge{a, b, u});
    }
  }
  std::sort(cuts.begin(), cuts.end());
  cuts.erase(
      std::unique(cuts.begin(), cuts.end(),
                  [](const CutEdge& p, const CutEdge& q) { return p.a == q.a && p.b == q.b; }),
      cuts.end());
  // 2. Every alive tet holding a cut edge is bisected too (conforming), found through the tree.
  std::vector<std::int32_t> split(tets.begin(), tets.end());
  std::vector<std::int32_t> near;
  if (!tree->BuiltFor(sb.tets.size())) {
    tree->Build(sb.x, sb.tets);
  } else {
    tree->Refit(sb.x, sb.tets);
  }
  for (const CutEdge& c : cuts) {
    collision::Box box;
    box.Add(sb.x.col(c.a));
    box.Add(sb.x.col(c.b));
    tree->QueryBox(sb.tet_alive, box, &near);
    for (std::int32_t t : near) {
      const mesh::Tet& e = sb.tets[static_cast<std::size_t>(t)];
      const bool has_a = std::find(e.begin(), e.end(), c.a) != e.end();
      const bool has_b = std::find(e.begin(), e.end(), c.b) != e.end();
      if (has_a && has_b) split.push_back(t);
    }
  }
  std::sort(split.begin(), split.end());
  split.erase(std::unique(split.begin(), split.end()), split.end());
  // 3. Sequential bisection by the cut edges in key order: a piece holding edge (a, b) becomes
  // (a -> m) and (b -> m); each keeps its orientation and a fraction u or 1 - u of the volume.
  std::vector<Piece> pieces;
  for (std::int32_t t : split) {
    std::vector<Piece> local{
        Piece{{sb.tets[static_cast<std::size_t>(t)][0], sb.tets[static_cast<std::size_t>(t)][1],
               sb.tets[static_cast<std::size_t>(t)][2], sb.tets[static_cast<std::size_t>(t)][3]},
              std::binary_search(tets.begin(), tets.end(), t)}};
    for (std::size_t k = 0; k < cuts.size(); ++k) {
      std::vector<Piece> next;
      for (const Piece& p : local) {
        const auto ia = std::find(p.v.begin(), p.v.end(), cuts[k].a);
        const auto ib = std::find(p.v.begin(), p.v.end(), cuts[k].b);
        if (ia == p.v.end() || ib == p.v.end()) {
          next.push_back(p);
          continue;
        }
        Piece q1 = p, q2 = p;
        q1.v[static_cast<std::size_t>(ia - p.v.begin())] = -1 - static_cast<std::int64_t>(k);
        q2.v[static_cast<std::size_t>(ib - p.v.begin())] = -1 - static_cast<std::int64_t>(k);
        next.push_back(q1);
        next.push_back(q2);
      }
      local.swap(next);
    }
    pieces.insert(pieces.end(), local.begin(), local.end());
    ++result.split_tets;
    result.volume_mm3 += TetRestVolume(sb, t);
  }
  // 4. Sides: a piece lies on the side of its centroid (edge points are on the plane).
  auto position = [&](std::int64_t v) -> Vec3 {
    if (v >= 0) return sb.x.col(v);
    const CutEdge& c = cuts[static_cast<std::size_t>(-1 - v)];
    return (1.0 - c.t) * sb.x.col(c.a) + c.t * sb.x.col(c.b);
  };
  std::vector<std::uint8_t> negative(pieces.size(), 0);
  for (std::size_t i = 0; i < pieces.size(); ++i) {
    Vec3 centroid = Vec3::Zero();
    for (std::int64_t v : pieces[i].v) centroid += position(v);
    negative[i] = normal.dot(0.25 * centroid - point) < 0 ? 1 : 0;
  }
  // 5. Separation: a node used by pieces of crossed tets on both sides (an edge point, or an
  // original node the cut passes through) gets a copy for the side it does not belong to (edge
  // points: the negative side; original nodes: the side opposite their own, where their other
  // elements are). Pieces of the other split tets (conforming neighbours at the rim of the cut)
  // keep the original: the cut ends there.
  std::vector<std::pair<std::int64_t, std::uint8_t>> uses;  // (node, side bit) of crossed pieces
  for (std::size_t i = 0; i < pieces.size(); ++i) {
    if (!pieces[i].crossed) continue;
    for (std::int64_t v : pieces[i].v) uses.emplace_back(v, negative[i] ? 2 : 1);
  }
  std::sort(uses.begin(), uses.end());
  std::vector<std::pair<std::int64_t, std::int32_t>> copies;  // node -> copy, ascending
  std::vector<std::array<std::int32_t, 4>> parents;
  std::vector<std::array<double, 4>> weights;
  for (const CutEdge& c : cuts) {
    parents.push_back({c.a, c.b, -1, -1});
    weights.push_back({1.0 - c.t, c.t, 0, 0});
  }
  const auto n0 = static_cast<std::int32_t>(sb.x.cols());
  for (std::size_t i = 0; i < uses.size();) {
    std::uint8_t sides = 0;
    std::size_t j = i;
    for (; j < uses.size() && uses[j].first == uses[i].first; ++j) sides |= uses[j].second;
    if (sides == 3 && uses[i].first < first_made) {
      const std::int64_t v = uses[i].first;
      copies.emplace_back(v, n0 + static_cast<std::int32_t>(parents.size()));
      if (v < 0) {
        const CutEdge& c = cuts[static_cast<std::size_t>(-1 - v)];
        parents.push_back({c.a, c.b, -1, -1});
        weights.push_back({1.0 - c.t, c.t, 0, 0});
      } else {
        parents.push_back({static_cast<std::int32_t>(v), -1, -1, -1});
        weights.push_back({1, 0, 0, 0});
      }
    }
    i = j;
  }
  if (cuts.empty() && copies.empty()) return SplitResult{};
  std::vector<mesh::Tet> out;
  out.reserve(pieces.size());
  for (std::size_t i = 0; i < pieces.size(); ++i) {
    mesh::Tet t{};
    for (int k = 0; k < 4; ++k) {
      const std::int64_t v = pieces[i].v[static_cast<std::size_t>(k)];
      // Which side the node itself belongs to: edge points to the positive one.
      const bool node_negative = v >= 0 && dist(static_cast<std::int32_t>(v)) < 0;
      const auto it = std::lower_bound(copies.begin(), copies.end(), std::make_pair(v, -1));
      const bool use_copy = pieces[i].crossed && it != copies.end() && it->first == v &&
                            (negative[i] != 0) != node_negative;
      t[static_cast<std::size_t>(k)] = use_copy ? it->second
                                                : (v >= 0 ? static_cast<std::int32_t>(v)
                                                          : n0 + static_cast<std::int32_t>(-1 - v));
    }
    out.push_back(t);
  }
  // 6. Apply: nodes first (interpolating x, v, x_rest), then the old tets out, the pieces in.
  soft->AppendNodes(model, body, parents, weights, state);
  soft->RemoveTets(body, split, state);
  soft->AppendTets(body, out, state);
  result.new_nodes = static_cast<int>(parents.size());
  result.new_tets = static_cast<int>(out.size());
  for (const mesh::Tet& t : out) {
    result.min_quality =
        std::min(result.min_quality, RadiusRatio(sb.x_rest.col(t[0]), sb.x_rest.col(t[1]),
                                                 sb.x_rest.col(t[2]), sb.x_rest.col(t[3])));
  }
  return result;
}

}  // namespace arthrosim::instruments
