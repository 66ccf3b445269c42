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
  std::int32_t parent = -1;    // the tet it comes from
  bool whole = false;          // the parent itself (a crossed tet the cut does not divide)
  bool one_sided_rim = false;  // a rim piece lying on one side: it takes that side's nodes
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

namespace {

// Node ids of pieces: >= 0 an existing node, < 0 the point of cut edge -1 - id.
using Id = std::int64_t;
using Corners = std::array<Id, 4>;

// The cut edges and the node classes of one split, for the decomposition below.
struct Section {
  std::vector<CutEdge> cuts;  // sorted by (a, b): their order decides shared diagonals
  // Index of cut edge (a, b) in `cuts`, or -1.
  int Find(std::int32_t a, std::int32_t b) const {
    if (a > b) std::swap(a, b);
    const auto it = std::lower_bound(cuts.begin(), cuts.end(), CutEdge{a, b, 0});
    return it != cuts.end() && it->a == a && it->b == b ? static_cast<int>(it - cuts.begin()) : -1;
  }
};

// Appends the tets of the pyramid with apex `apex` over the quad q0 q1 q2 q3 (in order round
// it), split by the diagonal q0-q2 (diag02) or q1-q3.
void Pyramid(Id apex, const std::array<Id, 4>& q, bool diag02, std::vector<Corners>* out) {
  if (diag02) {
    out->push_back({apex, q[0], q[1], q[2]});
    out->push_back({apex, q[0], q[2], q[3]});
  } else {
    out->push_back({apex, q[1], q[2], q[3]});
    out->push_back({apex, q[1], q[3], q[0]});
  }
}

// Appends the three tets of the prism with triangles (b0 b1 b2) and (t0 t1 t2), b_i joined to
// t_i. diag[i] is the diagonal of side i, the quad (b_i, b_j, t_j, t_i) with j = i + 1 mod 3:
// true for b_i-t_j, false for b_j-t_i. Three diagonals that all turn the same way (all equal)
// cannot be split without an inner node: callers never pass them.
void Prism(const std::array<Id, 3>& b, const std::array<Id, 3>& t, const std::array<bool, 3>& diag,
           std::vector<Corners>* out) {
  for (std::size_t i = 0; i < 3; ++i) {
    const std::size_t j = (i + 1) % 3, k = (i + 2) % 3;
    // Bottom corner b_i holds the diagonals of sides i (b_i-t_j) and k (b_i-t_k): the tet of
    // b_i and the top triangle, then the pyramid of b_i over side j.
    if (diag[i] && !diag[k]) {
      out->push_back({b[i], t[0], t[1], t[2]});
      Pyramid(b[i], {b[j], b[k], t[k], t[j]}, diag[j], out);
      return;
    }
    // Top corner t_i holds the diagonals of sides i (b_j-t_i) and k (b_k-t_i).
    if (!diag[i] && diag[k]) {
      out->push_back({t[i], b[0], b[1], b[2]});
      Pyramid(t[i], {b[j], b[k], t[k], t[j]}, diag[j], out);
      return;
    }
  }
  throw std::logic_error("SplitTetsByPlane: cyclic prism diagonals");
}

// The point of cut edge (a, b) as a piece id.
Id Point(const Section& sec, std::int32_t a, std::int32_t b) { return -1 - sec.Find(a, b); }

// Whether cut edge (a, b) comes before cut edge (c, d) in cut order.
bool Before(const Section& sec, std::int32_t a, std::int32_t b, std::int32_t c, std::int32_t d) {
  return sec.Find(a, b) < sec.Find(c, d);
}

// Pieces of a crossed tet whose nodes have classes cls (+1, -1, 0 on the plane): the plane
// through its on-plane nodes and its edge points cuts it into one convex piece per side, split
// into tets. The quads on the tet's faces take the diagonal the rim bisection gives them (the
// point of the earlier cut edge to the far end of the later one); a quad on the cut plane is
// free. side[i] is the side (+1 / -1) of piece i; a tet on one side only is its own piece.
void CutCrossedTet(const Section& sec, const mesh::Tet& e, const std::array<int, 4>& cls,
                   std::vector<Corners>* out, std::vector<int>* side) {
  std::vector<std::int32_t> pos, neg, zero;
  for (std::size_t i = 0; i < 4; ++i) (cls[i] > 0 ? pos : cls[i] < 0 ? neg : zero).push_back(e[i]);
  auto add = [&](std::size_t from, int sgn) { side->insert(side->end(), out->size() - from, sgn); };
  if (pos.empty() || neg.empty()) {
    out->push_back({e[0], e[1], e[2], e[3]});
    side->push_back(pos.empty() ? (neg.empty() ? 0 : -1) : 1);
    return;
  }
  // One node alone on its side: `lone` (sign sgn) against `others`.
  const bool pos_alone = pos.size() == 1;
  if (pos.size() == 1 || neg.size() == 1) {
    const std::int32_t s = pos_alone ? pos[0] : neg[0];
    const std::vector<std::int32_t>& o = pos_alone ? neg : pos;
    const int sgn = pos_alone ? 1 : -1;
    if (o.size() == 1) {  // two nodes on the plane: one cut edge
      const Id m = Point(sec, s, o[0]);
      out->push_back({m, o[0], zero[0], zero[1]});
      side->push_back(-sgn);
      out->push_back({s, m, zero[0], zero[1]});
      side->push_back(sgn);
      return;
    }
    if (o.size() == 2) {  // one node on the plane: a tet and a pyramid
      const Id mx = Point(sec, s, o[0]), my = Point(sec, s, o[1]);
      out->push_back({s, mx, my, zero[0]});
      side->push_back(sgn);
      std::size_t from = out->size();
      Pyramid(zero[0], {o[0], o[1], my, mx}, !Before(sec, s, o[0], s, o[1]), out);
      add(from, -sgn);
      return;
    }
    // Three against one: a tet and a prism.
    const Id mx = Point(sec, s, o[0]), my = Point(sec, s, o[1]), mw = Point(sec, s, o[2]);
    out->push_back({s, mx, my, mw});
    side->push_back(sgn);
    const std::size_t from = out->size();
    Prism({o[0], o[1], o[2]}, {mx, my, mw},
          {Before(sec, s, o[1], s, o[0]), Before(sec, s, o[2], s, o[1]),
           Before(sec, s, o[0], s, o[2])},
          out);
    add(from, -sgn);
    return;
  }
  // Two against two: a prism on each side.
  const std::int32_t p = pos[0], q = pos[1], x = neg[0], y = neg[1];
  const Id px = Point(sec, p, x), py = Point(sec, p, y), qx = Point(sec, q, x),
           qy = Point(sec, q, y);
  // Side 1 of both prisms is the section quad (px, py, qy, qx): both take the same diagonal
  // (true: px-qy), since at rest the four points need not be coplanar. One that leaves neither
  // prism cyclic always exists (the other would need the four cut edges in a cyclic order).
  std::array<bool, 3> d{Before(sec, q, x, p, x), false, Before(sec, p, y, q, y)};
  std::array<bool, 3> f{Before(sec, p, y, p, x), false, Before(sec, q, x, q, y)};
  const bool section = d[0] == d[2] ? !d[0] : (f[0] == f[2] ? !f[0] : true);
  d[1] = f[1] = section;
  std::size_t from = out->size();
  Prism({p, px, py}, {q, qx, qy}, d, out);
  add(from, 1);
  from = out->size();
  Prism({x, px, qx}, {y, py, qy}, f, out);
  add(from, -1);
}

// Pieces of a rim tet (not crossed, holding cut edges): bisected at its cut edges one after the
// other in cut order; a piece holding edge (a, b) becomes (a -> m) and (b -> m).
void BisectRimTet(const Section& sec, const mesh::Tet& e, std::vector<Corners>* out) {
  std::vector<Corners> local{{e[0], e[1], e[2], e[3]}}, next;
  for (std::size_t k = 0; k < sec.cuts.size(); ++k) {
    next.clear();
    for (const Corners& p : local) {
      const auto ia = std::find(p.begin(), p.end(), sec.cuts[k].a);
      const auto ib = std::find(p.begin(), p.end(), sec.cuts[k].b);
      if (ia == p.end() || ib == p.end()) {
        next.push_back(p);
        continue;
      }
      Corners q1 = p, q2 = p;
      q1[static_cast<std::size_t>(ia - p.begin())] = -1 - static_cast<Id>(k);
      q2[static_cast<std::size_t>(ib - p.begin())] = -1 - static_cast<Id>(k);
      next.push_back(q1);
      next.push_back(q2);
    }
    local.swap(next);
  }
  out->insert(out->end(), local.begin(), local.end());
}

// A node used on both sides of a cut: the node each side's pieces use instead.
struct SideNodes {
  std::int64_t node = 0;
  std::int32_t positive = -1, negative = -1;
};

// Nodes made by splits (ids >= first_made) grouped by exact rest position: a copy has its
// original's rest position bit for bit.
class RestTwins {
 public:
  RestTwins(const SoftBodyState& sb, std::int32_t first_made) : sb_(&sb) {
    for (std::int32_t n = first_made; n < static_cast<std::int32_t>(sb.x_rest.cols()); ++n)
      made_.emplace_back(Key(n), n);
    std::sort(made_.begin(), made_.end());
    // The original nodes copies were made of (same rest position): twins of their copies.
    const std::size_t made_count = made_.size();
    if (made_count == 0) return;
    for (std::int32_t n = 0; n < first_made; ++n) {
      const auto k = Key(n);
      const auto it =
          std::lower_bound(made_.begin(), made_.begin() + made_count, std::make_pair(k, -1));
      if (it != made_.begin() + made_count && it->first == k) made_.emplace_back(k, n);
    }
    std::sort(made_.begin(), made_.end());
  }
  /// n and the nodes at its rest position (made by splits, or the original they copy),
  /// ascending.
  std::vector<std::int32_t> Of(std::int32_t n) const {
    std::vector<std::int32_t> out{n};
    const auto k = Key(n);
    for (auto it = std::lower_bound(made_.begin(), made_.end(), std::make_pair(k, -1));
         it != made_.end() && it->first == k; ++it)
      if (it->second != n) out.push_back(it->second);
    std::sort(out.begin(), out.end());
    return out;
  }

 private:
  std::array<double, 3> Key(std::int32_t n) const {
    return {sb_->x_rest(0, n), sb_->x_rest(1, n), sb_->x_rest(2, n)};
  }
  const SoftBodyState* sb_;
  std::vector<std::pair<std::array<double, 3>, std::int32_t>> made_;
};

// The alive tets outside `split` (ascending) that hold node n and lie on one side of the plane,
// appended to *out as (tet, side +1 / -1), through the tree (refit). A node counts as on the
// plane if it was made by a split (id >= first_made) or lies within snap_fraction of the tet's
// longest edge from the plane; a tet with nodes off the plane on both sides (beyond the rim of
// the cut, where the blade did not reach) is left out: the cut ends there.
void UnsplitTetsAt(const SoftBodyState& sb, std::int32_t n, const std::vector<std::int32_t>& split,
                   const collision::TetTree* tree, const Vec3& point, const Vec3& normal,
                   double snap_fraction, std::int32_t first_made, std::vector<std::int32_t>* near,
                   std::vector<std::pair<std::int32_t, int>>* out) {
  collision::Box box;
  box.Add(sb.x.col(n));
  tree->QueryBox(sb.tet_alive, box, near);
  for (std::int32_t t : *near) {
    const mesh::Tet& e = sb.tets[static_cast<std::size_t>(t)];
    if (std::find(e.begin(), e.end(), n) == e.end() ||
        std::binary_search(split.begin(), split.end(), t))
      continue;
    double longest = 0;
    for (const auto& k : kEdges)
      longest = std::max(longest, (sb.x.col(e[k[0]]) - sb.x.col(e[k[1]])).norm());
    const double tol = snap_fraction * longest;
    bool above = false, below = false;
    Vec3 centroid = Vec3::Zero();
    for (std::int32_t m : e) {
      centroid += sb.x.col(m);
      if (m >= first_made) continue;
      const double d = normal.dot(Vec3(sb.x.col(m)) - point);
      above |= d > tol;
      below |= d < -tol;
    }
    if (above && below) continue;
    const int sgn = above ? 1 : (below ? -1 : (normal.dot(0.25 * centroid - point) < 0 ? -1 : 1));
    out->emplace_back(t, sgn);
  }
}

}  // namespace

SplitResult SplitTetsByPlane(const Model& model, int body, std::span<const std::int32_t> tets,
                             const Vec3& point, const Vec3& normal, double snap_fraction,
                             collision::TetTree* tree, physics::SoftSystem* soft, State* state) {
  SplitResult result;
  if (!(snap_fraction >= 0 && snap_fraction < 0.5)) {
    throw std::invalid_argument("SplitTetsByPlane: snap_fraction must be in [0, 0.5)");
  }
  SoftBodyState& sb = state->soft_bodies[static_cast<std::size_t>(body)];
  auto dist = [&](std::int32_t n) { return normal.dot(Vec3(sb.x.col(n)) - point); };
  // Nodes made by earlier splits lie on an earlier cut surface: they count as on the plane (a
  // later cut passes through them, never cuts an edge at them) and are never duplicated again,
  // so cutting near an existing cut does not refine it step after step.
  const auto first_made = static_cast<std::int32_t>(
      model.soft_bodies[static_cast<std::size_t>(body)].rest_mesh.nodes.cols());
  // 1. Node classes over the crossed tets: +1 / -1 by side, 0 on the plane. A node is on the
  // plane (snapped) when it is exactly on it, was made by a split, or some edge of a crossed tet
  // from it to the other side crosses the plane within snap_fraction of the edge from it.
  std::vector<std::pair<std::int32_t, int>> side;  // node -> class, ascending
  for (std::int32_t t : tets)
    for (std::int32_t n : sb.tets[static_cast<std::size_t>(t)]) {
      const double d = dist(n);
      side.emplace_back(n, n >= first_made || d == 0 ? 0 : (d > 0 ? 1 : -1));
    }
  std::sort(side.begin(), side.end());
  side.erase(std::unique(side.begin(), side.end()), side.end());
  auto class_of = [&](std::int32_t n) -> int& {
    return std::lower_bound(side.begin(), side.end(), std::make_pair(n, -2))->second;
  };
  std::vector<std::int32_t> snapped;
  for (std::int32_t t : tets) {
    const mesh::Tet& e = sb.tets[static_cast<std::size_t>(t)];
    for (const auto& k : kEdges) {
      const std::int32_t a = e[k[0]], b = e[k[1]];
      if (class_of(a) * class_of(b) >= 0) continue;
      const double u = dist(a) / (dist(a) - dist(b));
      if (u < snap_fraction) snapped.push_back(a);
      if (u > 1.0 - snap_fraction) snapped.push_back(b);
    }
  }
  for (std::int32_t n : snapped) class_of(n) = 0;
  // 2. Cut edges: the crossed tets' edges between the two sides (crossings in [snap, 1 - snap]
  // of the edge, by step 1).
  Section sec;
  for (std::int32_t t : tets) {
    const mesh::Tet& e = sb.tets[static_cast<std::size_t>(t)];
    for (const auto& k : kEdges) {
      std::int32_t a = e[k[0]], b = e[k[1]];
      if (class_of(a) * class_of(b) >= 0) continue;
      if (a > b) std::swap(a, b);
      sec.cuts.push_back(CutEdge{a, b, dist(a) / (dist(a) - dist(b))});
    }
  }
  std::sort(sec.cuts.begin(), sec.cuts.end());
  sec.cuts.erase(
      std::unique(sec.cuts.begin(), sec.cuts.end(),
                  [](const CutEdge& p, const CutEdge& q) { return p.a == q.a && p.b == q.b; }),
      sec.cuts.end());
  const std::vector<CutEdge>& cuts = sec.cuts;
  // 3. The tets to split: the crossed ones and every alive tet holding a cut edge (its
  // neighbours at the rim of the cut, bisected so the mesh stays conforming).
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
  // Where piece corner v lies in `points` (the current or the rest positions).
  auto corner = [&](const Points& points, Id v) -> Vec3 {
    if (v >= 0) return points.col(v);
    const CutEdge& c = cuts[static_cast<std::size_t>(-1 - v)];
    return (1.0 - c.t) * points.col(c.a) + c.t * points.col(c.b);
  };
  auto position = [&](Id v) { return corner(sb.x, v); };
  auto rest_position = [&](Id v) { return corner(sb.x_rest, v); };
  // 4. Pieces. A crossed tet is cut by the plane through its on-plane nodes and edge points
  // into one piece per side (a tet, a pyramid or a prism, each split into tets); a rim tet is
  // bisected at its cut edges one after the other in cut order. A quad on a face of the
  // original tet takes the diagonal bisection in cut order gives it (from the point of the
  // earlier cut edge to the far end of the later one), so both tets sharing the face split it
  // alike.
  // A node of the cut surface: an edge point of this cut, a node made by an earlier one, or a
  // node of a crossed tet on the plane (snapped).
  auto crossed_on_plane = [&](Id v) {
    const auto it = std::lower_bound(side.begin(), side.end(),
                                     std::make_pair(static_cast<std::int32_t>(v), -2));
    return it != side.end() && it->first == v && it->second == 0;
  };
  auto on_plane = [&](Id v) { return v < 0 || v >= first_made || crossed_on_plane(v); };
  // The side (+1 / -1) a rim piece lies on, 0 if it straddles the plane (nodes off the cut
  // surface beyond snap_fraction of its longest edge on both sides: the cut ends there) or has
  // no node off it. A rim piece on one side holds the crack tip's edge points and on-plane
  // nodes like the crossed pieces on that side: keeping the positive side's node there would
  // join the negative side's rim to the positive side and leave the negative copy held by a
  // lone crossed piece (a flap hanging on one edge, docs/operations.md).
  auto rim_piece_side = [&](const Corners& c) {
    double longest = 0;
    for (const auto& k : kEdges)
      longest = std::max(longest, (position(c[k[0]]) - position(c[k[1]])).norm());
    const double tol = snap_fraction * longest;
    bool above = false, below = false;
    for (Id v : c) {
      if (on_plane(v)) continue;
      const double d = dist(static_cast<std::int32_t>(v));
      above |= d > tol;
      below |= d < -tol;
    }
    return above == below ? 0 : (above ? 1 : -1);
  };
  std::vector<Piece> pieces;
  std::vector<std::uint8_t> negative;
  for (std::int32_t t : split) {
    const mesh::Tet& e = sb.tets[static_cast<std::size_t>(t)];
    const bool crossed = std::binary_search(tets.begin(), tets.end(), t);
    std::vector<Corners> local;
    std::vector<int> local_side;
    if (crossed) {
      const std::array<int, 4> cls{class_of(e[0]), class_of(e[1]), class_of(e[2]), class_of(e[3])};
      CutCrossedTet(sec, e, cls, &local, &local_side);
    } else {
      BisectRimTet(sec, e, &local);
    }
    for (std::size_t i = 0; i < local.size(); ++i) {
      Corners c = local[i];
      // Orientation: positive at rest like the parent (swap two corners if not).
      if (SignedVolume(rest_position(c[0]), rest_position(c[1]), rest_position(c[2]),
                       rest_position(c[3])) < 0)
        std::swap(c[2], c[3]);
      pieces.push_back(
          Piece{c, crossed, t, local.size() == 1 && c == Corners{e[0], e[1], e[2], e[3]}});
      int sgn = crossed ? local_side[i] : 0;
      if (!crossed) {
        sgn = rim_piece_side(c);
        pieces.back().one_sided_rim = sgn != 0;
      }
      if (sgn == 0) {
        Vec3 centroid = Vec3::Zero();
        for (Id v : c) centroid += position(v);
        sgn = normal.dot(0.25 * centroid - point) < 0 ? -1 : 1;
      }
      negative.push_back(sgn < 0 ? 1 : 0);
    }
  }
  // 5. Separation: a node used on both sides (by pieces of crossed tets, by the rim pieces on
  // one side for a node on the cut surface, or, for a node on the plane, by those and the
  // unsplit tets around it lying on one side) has one node per side. The positive side keeps an
  // edge point, an original node keeps its own side; the other side takes a twin: a node at the
  // same rest position (a copy an earlier cut made, or the original a copy was made of: the cut
  // goes on through it, and its side stays one piece), else a new copy. Of made twins, the
  // lowest id (the edge point) is the positive side's. Unsplit tets at the node on the side it
  // does not keep are replaced by the same tet on the side's node. Rim pieces straddling the
  // plane (conforming neighbours beyond the blade's reach) keep their nodes: the cut ends there.
  std::vector<std::pair<std::int64_t, std::uint8_t>> uses;  // (node, side bit)
  for (std::size_t i = 0; i < pieces.size(); ++i) {
    if (pieces[i].crossed) {
      for (std::int64_t v : pieces[i].v) uses.emplace_back(v, negative[i] ? 2 : 1);
    } else if (pieces[i].one_sided_rim) {
      for (std::int64_t v : pieces[i].v)
        if (on_plane(v)) uses.emplace_back(v, negative[i] ? 2 : 1);
    }
  }
  std::sort(uses.begin(), uses.end());
  std::vector<std::array<std::int32_t, 4>> parents;
  std::vector<std::array<double, 4>> weights;
  for (const CutEdge& c : cuts) {
    parents.push_back({c.a, c.b, -1, -1});
    weights.push_back({1.0 - c.t, c.t, 0, 0});
  }
  const auto n0 = static_cast<std::int32_t>(sb.x.cols());
  const RestTwins twins(sb, first_made);
  auto new_copy = [&](std::int32_t of) {
    parents.push_back({of, -1, -1, -1});
    weights.push_back({1, 0, 0, 0});
    return n0 + static_cast<std::int32_t>(parents.size()) - 1;
  };
  std::vector<SideNodes> sided;  // ascending by node
  // Unsplit tets at a made node of the cut, with their side: (tet, side) per made node, in
  // node order; `around` holds the current node's.
  std::vector<std::pair<std::int32_t, int>> around;
  std::vector<std::pair<std::int32_t, std::pair<std::int32_t, std::int32_t>>> renode;
  for (std::size_t i = 0; i < uses.size();) {
    std::uint8_t sides = 0;
    std::size_t j = i;
    for (; j < uses.size() && uses[j].first == uses[i].first; ++j) sides |= uses[j].second;
    const std::int64_t v = uses[i].first;
    // A node on the plane (snapped, or made by an earlier cut: e.g. an edge point at the rim
    // where an earlier step's cut ended) also holds the tets around it that were not split and
    // lie on one side: each counts on its side, so the cut going on through the node parts them
    // too (else the two sides stay joined there). On a fresh mesh these all lie on the node's
    // own side; after earlier cuts they may lie on both.
    around.clear();
    if (v >= 0 && on_plane(v)) {
      UnsplitTetsAt(sb, static_cast<std::int32_t>(v), split, tree, point, normal, snap_fraction,
                    first_made, &near, &around);
      for (const auto& [t, sgn] : around) sides |= sgn < 0 ? 2 : 1;
    }
    i = j;
    if (sides != 3) continue;
    if (v < 0) {  // an edge point of this cut: positive side, a copy for the negative one
      const CutEdge& c = cuts[static_cast<std::size_t>(-1 - v)];
      parents.push_back({c.a, c.b, -1, -1});
      weights.push_back({1.0 - c.t, c.t, 0, 0});
      sided.push_back({v, n0 + static_cast<std::int32_t>(-1 - v),
                       n0 + static_cast<std::int32_t>(parents.size()) - 1});
      continue;
    }
    const auto n = static_cast<std::int32_t>(v);
    std::vector<std::int32_t> set = twins.Of(n);  // ascending, n included
    if (set[0] < first_made) {
      // An original node (n, or the original n is a copy of) keeps its own side; the other
      // side takes its copy (else a copy of a copy would split that side at the node).
      const std::int32_t orig = set[0];
      const std::int32_t other = set.size() > 1 ? set[1] : new_copy(orig);
      sided.push_back(dist(orig) < 0 ? SideNodes{v, other, orig} : SideNodes{v, orig, other});
    } else {
      // Made nodes: the edge point (lower id) is the positive side's, its copy the negative's.
      sided.push_back({v, set[0], set.size() > 1 ? set[1] : new_copy(set[0])});
    }
    // Unsplit tets at n on the side whose node is not n take that side's node.
    for (const auto& [t, sgn] : around) {
      const std::int32_t to = sgn < 0 ? sided.back().negative : sided.back().positive;
      if (to != n) renode.push_back({t, {n, to}});
    }
  }
  std::sort(renode.begin(), renode.end());
  if (cuts.empty() && sided.empty()) return SplitResult{};
  // A crossed tet the cut does not divide is replaced only when one of its nodes changes to a
  // copy (else it stays as it is: no churn of identical tets step after step).
  std::vector<mesh::Tet> out;
  std::vector<std::int32_t> replaced;
  out.reserve(pieces.size());
  for (std::size_t i = 0; i < pieces.size(); ++i) {
    mesh::Tet t{};
    for (int k = 0; k < 4; ++k) {
      const std::int64_t v = pieces[i].v[static_cast<std::size_t>(k)];
      const auto it =
          std::lower_bound(sided.begin(), sided.end(), v,
                           [](const SideNodes& sn, std::int64_t x) { return sn.node < x; });
      std::int32_t id =
          v >= 0 ? static_cast<std::int32_t>(v) : n0 + static_cast<std::int32_t>(-1 - v);
      if ((pieces[i].crossed || pieces[i].one_sided_rim) && it != sided.end() && it->node == v)
        id = negative[i] ? it->negative : it->positive;
      t[static_cast<std::size_t>(k)] = id;
    }
    const bool same = pieces[i].whole && t == sb.tets[static_cast<std::size_t>(pieces[i].parent)];
    if (same) continue;
    out.push_back(t);
    if (replaced.empty() || replaced.back() != pieces[i].parent) {
      replaced.push_back(pieces[i].parent);
      ++result.split_tets;
      result.volume_mm3 += TetRestVolume(sb, pieces[i].parent);
    }
  }
  // Unsplit tets whose nodes change to the other side's copy of a made node: replaced by the
  // same tet with the new nodes (same rest shape).
  for (std::size_t i = 0; i < renode.size();) {
    const std::int32_t t = renode[i].first;
    mesh::Tet e = sb.tets[static_cast<std::size_t>(t)];
    for (; i < renode.size() && renode[i].first == t; ++i)
      std::replace(e.begin(), e.end(), renode[i].second.first, renode[i].second.second);
    out.push_back(e);
    replaced.push_back(t);
  }
  if (out.empty()) return SplitResult{};
  // 6. Apply: nodes first (interpolating x, v, x_rest), then the old tets out, the pieces in.
  soft->AppendNodes(model, body, parents, weights, state);
  soft->RemoveTets(body, replaced, state);
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
