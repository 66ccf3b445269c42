#include "arthrosim/collision/contact_generation.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <span>
#include <tuple>

#include "arthrosim/core/parallel.h"

namespace arthrosim::collision {
namespace {

using Kind = ConstraintEnd::Kind;
using physics::PointContact;

// Below this separation (mm) a closest-point direction is numerically meaningless; the contact
// normal then comes from the surface instead.
constexpr double kMinDirection = 1e-9;

// Extra search radius (mm) beyond the contact reach of the soft-soft and bone tip-soft searches:
// what a point found that far out may move (with the surface's drift) before it is searched again.
constexpr double kFarSlack = 2.0;

// Rounding allowance (mm) of the out-of-reach bounds: distances are computed to ~1e-12 mm.
constexpr double kCertSlack = 1e-6;

Vec3 SafeNormalized(const Vec3& v, const Vec3& fallback) {
  const double n = v.norm();
  return n > kMinDirection ? Vec3(v / n) : fallback;
}

void FillPositions(const Points& x, const std::vector<std::int32_t>& ids, std::vector<Vec3>* out) {
  out->resize(ids.size());
  for (std::size_t i = 0; i < ids.size(); ++i) (*out)[i] = x.col(ids[i]);
}

Vec3 FaceNormal(const std::vector<Vec3>& p, const mesh::Tri& t) {
  return SafeNormalized((p[t[1]] - p[t[0]]).cross(p[t[2]] - p[t[0]]), Vec3::UnitZ());
}

Vec3 VertexNormal(const Surface& s, const std::vector<Vec3>& p, std::int32_t v) {
  Vec3 n = Vec3::Zero();
  for (std::int32_t k = s.vertex_tri_start[v]; k < s.vertex_tri_start[v + 1]; ++k) {
    const mesh::Tri& t = s.local_tris[s.vertex_tris[k]];
    n += (p[t[1]] - p[t[0]]).cross(p[t[2]] - p[t[0]]);  // area weighted
  }
  return SafeNormalized(n, Vec3::UnitZ());
}

Simplex LocalTriangle(const std::vector<Vec3>& p, const mesh::Tri& t) {
  return TriangleSimplex(p[t[0]], p[t[1]], p[t[2]]);
}

Box SimplexBox(const Simplex& s) {
  Box b;
  for (int i = 0; i < s.n; ++i) b.Add(s.v[i]);
  return b;
}

// Nearest surface feature to a query simplex among candidate triangles, with the pseudo-normal
// of all equally near triangles (sum of their face normals) to tell inside from outside at
// edges and vertices.
struct Nearest {
  bool found = false;
  std::int32_t tri = -1;
  ClosestPair pair;  // a = query, b = triangle
  double dist = 0;
  Vec3 pseudo = Vec3::UnitZ();
  /// Signed distance of the query point from the surface (> 0 outside), mm.
  double Signed() const { return (pair.pa - pair.pb).dot(pseudo) >= 0 ? dist : -dist; }
};

// Squared distance between two boxes (0 if they overlap), mm^2: a lower bound of the distance
// of any two points in them.
double BoxDist2(const Box& a, const Box& b) {
  double d2 = 0;
  for (int k = 0; k < 3; ++k) {
    const double g = std::max(std::max(a.lo[k] - b.hi[k], b.lo[k] - a.hi[k]), 0.0);
    d2 += g * g;
  }
  return d2;
}

// The nearest triangle among the candidates, as if each were tested in ascending order (the
// first of exactly equal minima wins), and the pseudo-normal summed over the ties in ascending
// order. The candidate with the nearest box is tested first; then a candidate whose box is
// clearly farther than the best so far is skipped: it can be neither the minimum nor a tie, so
// the result is the same as testing them all. `qbox` bounds the query, `bvh` holds the
// triangles' boxes. `hint` (e.g. last step's nearest triangle), if among the candidates, is
// tested first instead: the order of the tests never changes the result (every minimum or tie
// is tested whatever the order, and equal minima go to the lowest index), a good first guess
// only lets more candidates be skipped.
Nearest NearestOnSurface(const Simplex& q, const Box& qbox, const std::vector<std::int32_t>& cand,
                         const TriangleBvh& bvh, const std::vector<Vec3>& p,
                         const std::vector<mesh::Tri>& tris, std::int32_t hint = -1) {
  Nearest best;
  const std::size_t n = cand.size();
  if (n == 0) return best;
  // Scratch on the stack for the usual handful of candidates.
  constexpr std::size_t kSmall = 64;
  double small_box[kSmall], small_d2[kSmall];
  thread_local std::vector<double> big_box, big_d2;
  double* box_d2 = small_box;
  double* d2 = small_d2;
  if (n > kSmall) {
    big_box.resize(n);
    big_d2.resize(n);
    box_d2 = big_box.data();
    d2 = big_d2.data();
  }
  std::fill(d2, d2 + n, -1.0);
  std::size_t first = 0;
  bool hinted = false;
  for (std::size_t i = 0; i < n; ++i) {
    box_d2[i] = BoxDist2(qbox, bvh.TriangleBox(cand[i]));
    if (cand[i] == hint) {
      first = i;
      hinted = true;
    } else if (!hinted && box_d2[i] < box_d2[first]) {
      first = i;
    }
  }
  // Beyond the tie tolerance below, with a wide margin for rounding: cannot matter.
  auto beyond = [&](double lower2) { return lower2 > best.pair.dist2 * (1 + 1e-6) + 1e-12; };
  auto test = [&](std::size_t i) {
    const mesh::Tri& t = tris[cand[i]];
    ClosestPair c;
    if (q.n == 1) {
      c = PointTriangle(q.v[0], p[t[0]], p[t[1]], p[t[2]]);
    } else if (!ClosestUnless(q, LocalTriangle(p, t),
                              best.found ? std::sqrt(best.pair.dist2 * (1 + 1e-6) + 1e-12) : -1.0,
                              &c)) {
      return;  // provably beyond the tie tolerance, like a far box
    }
    d2[i] = c.dist2;
    if (!best.found || c.dist2 < best.pair.dist2 ||
        (c.dist2 == best.pair.dist2 && cand[i] < best.tri)) {
      best.found = true;
      best.tri = cand[i];
      best.pair = c;
    }
  };
  test(first);
  for (std::size_t i = 0; i < n; ++i) {
    if (i == first || beyond(box_d2[i])) continue;
    test(i);
  }
  best.dist = std::sqrt(best.pair.dist2);
  const double tie = best.pair.dist2 * (1 + 1e-9) + 1e-18;
  Vec3 sum = Vec3::Zero();
  for (std::size_t i = 0; i < n; ++i) {
    if (d2[i] >= 0 && d2[i] <= tie) sum += FaceNormal(p, tris[cand[i]]);
  }
  const double len = sum.norm();
  best.pseudo = len > kMinDirection ? Vec3(sum / len) : FaceNormal(p, tris[best.tri]);
  return best;
}

// Culling tests are conservative by this much (mm), so rounding never drops a true candidate.
constexpr double kCullSlack = 1e-6;

// True if box a grown by m overlaps box b.
bool NearBoxes(const Box& a, double m, const Box& b) {
  return (a.lo.array() - m <= b.hi.array()).all() && (b.lo.array() <= a.hi.array() + m).all();
}

// Conservative: may some point of box b lie within `reach` of the simplex `core` (whose box is
// core_box)? Box test, then the ball around b's centre through its corners against the core.
bool BoxNearCore(const Box& core_box, const Simplex& core, double reach, const Box& b) {
  if (!NearBoxes(core_box, reach + kCullSlack, b)) return false;
  const Vec3 c = 0.5 * (b.lo + b.hi);
  const double lim = reach + 0.5 * (b.hi - b.lo).norm() + kCullSlack;
  return Closest(PointSimplex(c), core).dist2 <= lim * lim;
}

// Conservative: false only when a triangle's plane separates the other simplex from it by more
// than `reach` (then no point pair is within reach). Cheap next to an exact triangle test.
bool PlanesAllowReach(const Simplex& a, const Simplex& b, double reach) {
  auto separated = [reach](const Simplex& t, const Simplex& o) {
    if (t.n != 3) return false;
    const Vec3 n = (t.v[1] - t.v[0]).cross(t.v[2] - t.v[0]);
    const double len = n.norm();
    if (!(len > 0)) return false;
    const double lim = (reach + kCullSlack) * len;
    double lo = n.dot(o.v[0] - t.v[0]), hi = lo;
    for (int i = 1; i < o.n; ++i) {
      const double d = n.dot(o.v[i] - t.v[0]);
      lo = std::min(lo, d);
      hi = std::max(hi, d);
    }
    return lo > lim || hi < -lim;
  };
  return !separated(a, b) && !separated(b, a);
}

// The tool primitive swept from last step's pose (sub[0]) to this step's (sub.back()).
struct Sweep {
  const ToolPrimitive* prim = nullptr;
  std::vector<Simplex> sub;
  std::vector<Box> sub_box;  // box of each substep core
  Box box;                   // of all substeps, not inflated

  /// Conservative: may some point of box b come within `reach` of the core at some substep?
  bool Near(double reach, const Box& b) const {
    if (!NearBoxes(box, reach + kCullSlack, b)) return false;
    for (std::size_t s = 0; s < sub.size(); ++s) {
      if (BoxNearCore(sub_box[s], sub[s], reach, b)) return true;
    }
    return false;
  }
};

// First substep at which the target (whose box is target_box) comes within `reach` of the swept
// core, -1 if none; `last`, if given, is the caller's Closest(sw.sub.back(), target). Substeps
// whose core box is farther than reach from target_box, or whose plane separates them, cannot
// touch: skipped without an exact test.
int FirstTouch(const Sweep& sw, double reach, const Simplex& target, const Box& target_box,
               ClosestPair* at, const ClosestPair* last = nullptr) {
  const double reach2 = reach * reach;
  const std::size_t n = sw.sub.size();
  for (std::size_t s = 0; s < n; ++s) {
    if (last != nullptr && s + 1 == n) {  // already computed by the caller
      if (!(last->dist2 < reach2)) return -1;
      *at = *last;
      return static_cast<int>(s);
    }
    if (!NearBoxes(sw.sub_box[s], reach + kCullSlack, target_box)) continue;
    if (!PlanesAllowReach(sw.sub[s], target, reach)) continue;
    ClosestPair c;
    if (!ClosestUnless(sw.sub[s], target, reach, &c)) continue;  // provably out of reach
    if (c.dist2 < reach2) {
      *at = c;
      return static_cast<int>(s);
    }
  }
  return -1;
}

// Support function of a simplex: max over its points of n . x, mm.
double Support(const Simplex& s, const Vec3& n) {
  double h = n.dot(s.v[0]);
  for (int i = 1; i < s.n; ++i) h = std::max(h, n.dot(s.v[i]));
  return h;
}

// Conservative: false when no substep can bring the target within reach (cheap tests only).
bool MayTouch(const Sweep& sw, double reach, const Simplex& target, const Box& target_box) {
  for (std::size_t s = 0; s < sw.sub.size(); ++s) {
    if (NearBoxes(sw.sub_box[s], reach + kCullSlack, target_box) &&
        PlanesAllowReach(sw.sub[s], target, reach)) {
      return true;
    }
  }
  return false;
}

// Closest(sw.sub.back(), target), reusing the touch when it happened at the last substep.
ClosestPair Now(const Sweep& sw, int touched_at, const ClosestPair& touch, const Simplex& target) {
  if (touched_at + 1 == static_cast<int>(sw.sub.size())) return touch;
  return Closest(sw.sub.back(), target);
}

struct Builder {
  const Model& model;
  const State& state;
  const CollisionParams& params;
  std::vector<PointContact>& contacts;  // scratch kept across steps: no allocation once warm
  std::vector<Kind>& kinds;

  void Add(const PointContact& c, Kind obstacle) {
    contacts.push_back(c);
    kinds.push_back(obstacle);
  }

  bool SoftFixed(int body, std::int32_t node) const {
    const auto& f = model.soft_bodies[body].fixed_nodes;
    return std::binary_search(f.begin(), f.end(), node);
  }
  bool ThreadFixed(int thread, std::int32_t node) const {
    const auto& f = model.threads[thread].fixed_nodes;
    return std::find(f.begin(), f.end(), node) != f.end();
  }
  bool ThreadAlive(int thread, std::int32_t node) const {
    const auto& a = state.threads[thread].node_alive;
    return node < static_cast<std::int32_t>(a.size()) && a[node] != 0;
  }
};

// Contact on a thread segment point with parameter u (0 = node a, 1 = node b).
PointContact ThreadPoint(int thread, std::int32_t a, std::int32_t b, double u) {
  PointContact c;
  c.target = PointContact::Target::kThread;
  c.index = thread;
  if (u <= 0) {
    c.nodes = {a, -1, -1, -1};
    c.weights = {1, 0, 0, 0};
  } else if (u >= 1) {
    c.nodes = {b, -1, -1, -1};
    c.weights = {1, 0, 0, 0};
  } else {
    c.nodes = {a, b, -1, -1};
    c.weights = {1 - u, u, 0, 0};
  }
  return c;
}

// ---- tool against soft tissue -------------------------------------------------------------

void ToolTissue(Builder* B, int slot, const Sweep& sw, int body, CollisionWorld::SoftEntry& e) {
  const CollisionParams& P = B->params;
  const double r = sw.prim->radius_mm;
  const double reach = r + P.alarm_distance_mm;
  const Box query = sw.box.Inflated(reach);
  if (e.bvh.empty() || !query.Overlaps(e.bvh.Bounds())) return;
  thread_local std::vector<std::int32_t> tris, verts;
  tris.clear();
  verts.clear();
  // Sized for the whole surface once, so a bigger overlap later does not allocate.
  tris.reserve(e.surface.local_tris.size());
  verts.reserve(3 * e.surface.local_tris.size());
  // Triangles that may come within reach of the core at some substep (every vertex within reach
  // is a corner of one of them).
  e.bvh.QueryIf([&](const Box& b) { return sw.Near(reach, b); }, &tris);
  for (std::int32_t t : tris) {
    for (std::int32_t v : e.surface.local_tris[t]) verts.push_back(v);
  }
  std::sort(verts.begin(), verts.end());
  verts.erase(std::unique(verts.begin(), verts.end()), verts.end());
  auto make = [&](const ClosestPair& touch, const ClosestPair& cur, const Vec3& fallback) {
    PointContact c;
    c.target = PointContact::Target::kSoftBody;
    c.index = body;
    // Direction fixed where the point first came within reach (outside the core, as the sweep
    // substep is below the alarm distance); the plane is this step's tangent plane of the tool
    // with that normal (support of the core), so the point is pushed ahead of the whole part
    // even where the core has passed it (a needle point through a triangle).
    (void)cur;
    c.normal = SafeNormalized(touch.pb - touch.pa, fallback);
    c.offset_mm = Support(sw.sub.back(), c.normal) + r + P.contact_distance_mm;
    c.stiffness_n_per_mm = P.tool_tissue_stiffness_n_per_mm;
    c.tool_slot = slot;
    c.obstacle_id = -1;
    return c;
  };
  // 1. Surface vertices.
  for (std::int32_t v : verts) {
    const std::int32_t node = e.surface.vertices[v];
    const Vec3& p = e.positions[v];
    if ((p.array() < query.lo.array()).any() || (p.array() > query.hi.array()).any()) continue;
    if (B->SoftFixed(body, node)) continue;
    ClosestPair touch;
    const int at = FirstTouch(sw, reach, PointSimplex(p), Box{p, p}, &touch);
    if (at < 0) continue;
    const ClosestPair cur = Now(sw, at, touch, PointSimplex(p));
    PointContact c = make(touch, cur, -VertexNormal(e.surface, e.positions, v));
    c.nodes = {node, -1, -1, -1};
    c.weights = {1, 0, 0, 0};
    B->Add(c, Kind::kTool);
  }
  // 2. Surface points between vertices: for each triangle within reach whose nearest point to
  // the tool is inside it or on an edge, a contact there, so a sharp or small part (blade edge,
  // awl point) cannot slip between vertices. Edge points are shared by two triangles: the first
  // (lowest canonical triangle) keeps it.
  thread_local std::vector<std::pair<std::int32_t, std::int32_t>> edges_done;
  edges_done.clear();
  for (std::int32_t t : tris) {
    const mesh::Tri& g = e.surface.tris[t];
    if (B->SoftFixed(body, g[0]) && B->SoftFixed(body, g[1]) && B->SoftFixed(body, g[2])) continue;
    const Simplex tri = LocalTriangle(e.positions, e.surface.local_tris[t]);
    // The current closest point first: at a vertex there is nothing to add (often the case),
    // and the last substep of the touch search is then known.
    if (!MayTouch(sw, reach, tri, e.bvh.TriangleBox(t))) continue;
    const ClosestPair cur = Closest(sw.sub.back(), tri);
    const auto& w = cur.wb;
    const int zeros = (w[0] <= 0) + (w[1] <= 0) + (w[2] <= 0);
    if (zeros >= 2) continue;  // at a vertex: the vertex contact covers it
    ClosestPair touch;
    if (FirstTouch(sw, reach, tri, e.bvh.TriangleBox(t), &touch, &cur) < 0) continue;
    if (zeros == 1) {
      const int k = w[0] <= 0 ? 0 : (w[1] <= 0 ? 1 : 2);
      const std::pair<std::int32_t, std::int32_t> edge{std::min(g[(k + 1) % 3], g[(k + 2) % 3]),
                                                       std::max(g[(k + 1) % 3], g[(k + 2) % 3])};
      if (std::find(edges_done.begin(), edges_done.end(), edge) != edges_done.end()) continue;
      edges_done.push_back(edge);
    }
    PointContact c = make(touch, cur, -FaceNormal(e.positions, e.surface.local_tris[t]));
    c.nodes = {g[0], g[1], g[2], -1};
    c.weights = {w[0], w[1], w[2], 0};
    B->Add(c, Kind::kTool);
  }
}

// ---- sharp tool point inside the tissue volume ---------------------------------------------

// Barycentric weights of p in tet (a, b, c, d); false if the tet is degenerate.
bool TetWeights(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d,
                std::array<double, 4>* w) {
  Eigen::Matrix3d m;
  m.col(0) = b - a;
  m.col(1) = c - a;
  m.col(2) = d - a;
  const double det = m.determinant();
  if (!(std::abs(det) > 1e-15)) return false;
  const Vec3 l = m.inverse() * (p - a);
  *w = {1 - l[0] - l[1] - l[2], l[0], l[1], l[2]};
  return true;
}

// A sharp point (the end v0 of an awl-point core) is held at tissue vertices and at one point
// per surface triangle; on coarse tissue the tented triangles around it fold and slide off
// sideways. So the material the point has gone through in this step is held too: each sweep
// substep position of the point that lies inside an alive tet (deformed, at t_n) gives a contact
// on that material point (the tet's four nodes, barycentric weights) pushing it ahead of the
// point along the part's axis, to the plane through the current point + radius + skin. The
// axis, not the surface normal, so a tented apex cannot be pushed sideways, and one-sided, so
// retracting the point releases the material.
void ToolVolume(Builder* B, int slot, const Sweep& sw, int body, const SoftBodyState& sb,
                const CollisionWorld::SoftEntry& e) {
  const CollisionParams& P = B->params;
  if (!P.sharp_point_volume_contacts || sw.prim->part != ToolPart::kAwlTip || sw.sub.back().n < 2) {
    return;
  }
  const Simplex& now = sw.sub.back();
  const Vec3 axis = SafeNormalized(now.v[0] - now.v[1], Vec3::UnitZ());
  const double reach = sw.prim->radius_mm + P.contact_distance_mm;
  // Material points: the point's position at each substep (what it went through this step) and
  // points ahead of it up to the alarm distance beyond its surface (what it may reach during the
  // solve: contacts exist before touching, as everywhere else).
  thread_local std::vector<Vec3> pts;
  pts.clear();
  for (const Simplex& s : sw.sub) pts.push_back(s.v[0]);
  const double ahead = reach + P.alarm_distance_mm;
  const int n_ahead = static_cast<int>(std::ceil(ahead / (P.sweep_fraction * P.alarm_distance_mm)));
  for (int j = 1; j <= n_ahead; ++j) pts.push_back(now.v[0] + (ahead * j / n_ahead) * axis);
  Box path;
  for (const Vec3& p : pts) path.Add(p);
  if (e.bvh.empty() || !path.Overlaps(e.bvh.Bounds())) return;
  // Four planes tilted toward the axis by atan(kEngage) (a pyramid ahead of the point): at the
  // axis each asks for `reach` ahead of the core end; a material point that slides sideways by l
  // must be kEngage * l further ahead, so it is pushed back toward the axis (the point has
  // engaged it, like friction mu = kEngage) instead of sliding off.
  constexpr double kEngage = 1.0;
  const double inv_len = 1 / std::sqrt(1 + kEngage * kEngage);
  const Vec3 e1 = axis.unitOrthogonal(), e2 = axis.cross(e1);
  const std::array<Vec3, 4> lateral{e1, -e1, e2, -e2};
  const std::size_t nsub = pts.size();
  thread_local std::vector<std::int32_t> owner;  // first tet holding each point
  thread_local std::vector<std::array<double, 4>> weights;
  owner.assign(nsub, -1);
  weights.assign(nsub, {0, 0, 0, 0});
  for (std::size_t t = 0; t < sb.tets.size(); ++t) {
    if (t < sb.tet_alive.size() && !sb.tet_alive[t]) continue;
    const mesh::Tet& tet = sb.tets[t];
    Box tb;
    for (std::int32_t n : tet) tb.Add(sb.x.col(n));
    if (!tb.Overlaps(path)) continue;
    for (std::size_t s = 0; s < nsub; ++s) {
      const Vec3& p = pts[s];
      if (owner[s] >= 0 || !tb.Overlaps(Box{p, p})) continue;
      std::array<double, 4> w;
      if (!TetWeights(p, sb.x.col(tet[0]), sb.x.col(tet[1]), sb.x.col(tet[2]), sb.x.col(tet[3]),
                      &w)) {
        continue;
      }
      if (*std::min_element(w.begin(), w.end()) < 0) continue;
      owner[s] = static_cast<std::int32_t>(t);
      weights[s] = w;
    }
  }
  auto engage = [&](const std::array<std::int32_t, 4>& nodes, const std::array<double, 4>& w) {
    for (const Vec3& side : lateral) {
      PointContact c;
      c.target = PointContact::Target::kSoftBody;
      c.index = body;
      c.nodes = nodes;
      c.weights = w;
      c.normal = (axis - kEngage * side) * inv_len;
      c.offset_mm = c.normal.dot(now.v[0]) + reach * inv_len;
      c.stiffness_n_per_mm = P.tool_volume_stiffness_n_per_mm;
      c.tool_slot = slot;
      B->Add(c, Kind::kTool);
    }
  };
  for (std::size_t s = 0; s < nsub; ++s) {
    if (owner[s] < 0) continue;
    const mesh::Tet& tet = sb.tets[owner[s]];
    if (B->SoftFixed(body, tet[0]) && B->SoftFixed(body, tet[1]) && B->SoftFixed(body, tet[2]) &&
        B->SoftFixed(body, tet[3])) {
      continue;
    }
    engage({tet[0], tet[1], tet[2], tet[3]}, weights[s]);
  }
  // Surface points on the point's path: where the segment from last step's point to `ahead`
  // beyond the current one crosses a boundary triangle (a thin membrane's far surface, which a
  // coarse tet may not hold in front of the point once it is squeezed).
  const Vec3 from = sw.sub.front().v[0], to = pts.back();
  const Vec3 dir = to - from;
  thread_local std::vector<std::int32_t> tris;
  tris.clear();
  Box seg;
  seg.Add(from);
  seg.Add(to);
  e.bvh.Query(seg, &tris);
  for (std::int32_t t : tris) {
    const mesh::Tri& g = e.surface.tris[t];
    const mesh::Tri& l = e.surface.local_tris[t];
    const Vec3 a = e.positions[l[0]], b = e.positions[l[1]], c = e.positions[l[2]];
    const Vec3 ab = b - a, ac = c - a, pv = dir.cross(ac);
    const double det = ab.dot(pv);
    if (!(std::abs(det) > 1e-15)) continue;  // parallel: the volume points hold it
    const Vec3 tv = from - a;
    const double u = tv.dot(pv) / det;
    const Vec3 qv = tv.cross(ab);
    const double v = dir.dot(qv) / det, f = ac.dot(qv) / det;
    if (u < 0 || v < 0 || u + v > 1 || f < 0 || f > 1) continue;
    if (B->SoftFixed(body, g[0]) && B->SoftFixed(body, g[1]) && B->SoftFixed(body, g[2])) continue;
    engage({g[0], g[1], g[2], -1}, {1 - u - v, u, v, 0});
  }
}

// ---- tool against thread ------------------------------------------------------------------

// Boxes of a thread's alive segments, and of runs of kRun consecutive segments (to skip a far
// thread fast); empty boxes for dead segments. Made once per step, used by every tool part.
constexpr std::size_t kRun = 8;
struct ThreadBoxes {
  std::vector<Box> seg, run;
};

void MakeThreadBoxes(const Model& model, const State& state, int thread, ThreadBoxes* out) {
  const ThreadModel& tm = model.threads[thread];
  const Points& x = state.threads[thread].x;
  const auto& alive = state.threads[thread].node_alive;
  auto is_alive = [&](std::int32_t node) {
    return node < static_cast<std::int32_t>(alive.size()) && alive[node] != 0;
  };
  const std::size_t ne = tm.initial.edges.size();
  out->seg.assign(ne, Box{});
  out->run.assign((ne + kRun - 1) / kRun, Box{});
  for (std::size_t i = 0; i < ne; ++i) {
    const std::int32_t a = tm.initial.edges[i][0], b = tm.initial.edges[i][1];
    if (!is_alive(a) || !is_alive(b)) continue;
    out->seg[i].Add(x.col(a));
    out->seg[i].Add(x.col(b));
    out->run[i / kRun].Add(x.col(a));
    out->run[i / kRun].Add(x.col(b));
  }
}

void ToolThread(Builder* B, int slot, const Sweep& sw, int thread, const ThreadBoxes& boxes) {
  const CollisionParams& P = B->params;
  const ThreadModel& tm = B->model.threads[thread];
  const Points& x = B->state.threads[thread].x;
  const double rt = 0.5 * tm.diameter_mm;
  const double r = sw.prim->radius_mm;
  const double reach = r + rt + P.alarm_distance_mm;
  const std::size_t ne = tm.initial.edges.size();
  const std::vector<Box>& seg_box = boxes.seg;
  const std::vector<Box>& run_box = boxes.run;
  std::int32_t last_single = -1;  // a node already given a contact by the previous segment
  for (std::size_t i = 0; i < ne; ++i) {
    if (i % kRun == 0 && (run_box[i / kRun].Empty() || !sw.Near(reach, run_box[i / kRun]))) {
      i += kRun - 1;
      continue;
    }
    const std::int32_t a = tm.initial.edges[i][0], b = tm.initial.edges[i][1];
    if (seg_box[i].Empty() || !sw.Near(reach, seg_box[i])) continue;
    const Simplex seg = SegmentSimplex(x.col(a), x.col(b));
    ClosestPair touch;
    const int at = FirstTouch(sw, reach, seg, seg_box[i], &touch);
    if (at < 0) continue;
    const ClosestPair cur = Now(sw, at, touch, seg);
    PointContact c = ThreadPoint(thread, a, b, cur.wb[1]);
    if (c.nodes[1] < 0) {
      if (c.nodes[0] == last_single) continue;
      last_single = c.nodes[0];
    }
    if (B->ThreadFixed(thread, c.nodes[0]) &&
        (c.nodes[1] < 0 || B->ThreadFixed(thread, c.nodes[1]))) {
      continue;
    }
    const Vec3 motion = sw.sub.back().At(touch.wa) - sw.sub.front().At(touch.wa);
    c.normal = SafeNormalized(touch.pb - touch.pa, SafeNormalized(motion, Vec3::UnitZ()));
    c.offset_mm = Support(sw.sub.back(), c.normal) + r + rt + P.contact_distance_mm;
    c.stiffness_n_per_mm = P.tool_thread_stiffness_n_per_mm;
    c.tool_slot = slot;
    B->Add(c, Kind::kTool);
  }
}

// ---- tool against bone: reaction on the kinematic tool only --------------------------------

void ToolBone(Builder* B, int slot, const Sweep& sw, CollisionWorld::BoneEntry& e,
              CollisionOutput* out, double* deepest, Vec3* deepest_point) {
  const double r = sw.prim->radius_mm;
  const Simplex& now = sw.sub.back();
  const double reach = r + B->params.contact_distance_mm;
  const Box now_box = SimplexBox(now);
  if (e.bvh.empty() || !NearBoxes(now_box, reach, e.bvh.Bounds())) return;
  thread_local std::vector<std::int32_t> tris;
  tris.clear();
  // Only triangles that may be within reach of the core: the nearest one when there is a
  // penetration (and all its equally near neighbours) are among them.
  e.bvh.QueryIf([&](const Box& b) { return BoxNearCore(now_box, now, reach, b); }, &tris);
  const Nearest n = NearestOnSurface(now, now_box, tris, e.bvh, e.positions, e.indexed.local_tris);
  if (!n.found) return;
  const double depth = r - n.Signed();
  if (depth <= 0) return;
  const Vec3 dir = n.Signed() > kMinDirection ? Vec3((n.pair.pa - n.pair.pb) / n.dist) : n.pseudo;
  out->bone_force_n[slot] += B->params.tool_bone_stiffness_n_per_mm * depth * dir;
  if (depth > *deepest) {
    *deepest = depth;
    *deepest_point = n.pair.pb;
  }
}

// ---- thread against a surface (tissue: both sides; bone: thread side) ---------------------

// A thread point (node or segment interior) near a surface: thread-side contact, and for soft
// tissue the reaction contact on the surface point.
void ThreadSurfaceContact(Builder* B, int thread, PointContact c, const Nearest& n, Kind obstacle,
                          int obstacle_index, const Surface& s, double rt, double stiffness) {
  const CollisionParams& P = B->params;
  const Vec3 normal =
      n.Signed() > kMinDirection ? Vec3((n.pair.pa - n.pair.pb) / n.dist) : n.pseudo;
  c.normal = normal;
  c.offset_mm = normal.dot(n.pair.pb) + rt + P.contact_distance_mm;
  c.stiffness_n_per_mm = stiffness;
  c.obstacle_id = obstacle_index;
  B->Add(c, obstacle);
  if (obstacle != Kind::kSoftBody) return;
  const mesh::Tri& g = s.tris[n.tri];
  if (B->SoftFixed(obstacle_index, g[0]) && B->SoftFixed(obstacle_index, g[1]) &&
      B->SoftFixed(obstacle_index, g[2])) {
    return;
  }
  PointContact t;
  t.target = PointContact::Target::kSoftBody;
  t.index = obstacle_index;
  t.nodes = {g[0], g[1], g[2], -1};
  t.weights = {n.pair.wb[0], n.pair.wb[1], n.pair.wb[2], 0};
  t.normal = -normal;
  t.offset_mm = -normal.dot(n.pair.pa) + rt + P.contact_distance_mm;
  t.stiffness_n_per_mm = stiffness;
  t.obstacle_id = thread;
  B->Add(t, Kind::kThread);
}

// `query(i, box, out)` lists the triangles whose box overlaps `box` (ascending) for query slot i
// (segment i - n for i >= n, n = node count; slots below n are left for node queries): a tree
// query, or a NearBoneCache lookup for a bone.
// `batch`: segment candidates come from `bvh` by one query per run of segments instead.
// `hint`: per node then segment, the last nearest triangle (search hints, kept by the caller).
template <class Query>
void ThreadSurface(Builder* B, int thread, Kind obstacle, int obstacle_index, const Surface& s,
                   const std::vector<Vec3>& pos, const TriangleBvh& bvh, double stiffness,
                   bool batch, std::vector<std::int32_t>* hint, const Query& query) {
  const CollisionParams& P = B->params;
  const ThreadModel& tm = B->model.threads[thread];
  const Points& x = B->state.threads[thread].x;
  const double rt = 0.5 * tm.diameter_mm;
  if (bvh.empty()) return;
  const Box bounds = bvh.Bounds();
  const double reach = std::max(rt + P.alarm_distance_mm, P.max_depth_mm);
  auto in_contact = [&](const Nearest& n) {
    const double sd = n.Signed();
    return sd >= 0 ? sd < rt + P.alarm_distance_mm : -sd < P.max_depth_mm;
  };
  const std::size_t ne = tm.initial.edges.size();
  const Eigen::Index nn = x.cols();
  thread_local std::vector<std::int32_t> tris;
  thread_local std::vector<Nearest> seg;
  thread_local std::vector<std::vector<std::int32_t>> seg_tris;  // candidates per segment
  thread_local std::vector<std::int32_t> node_seg;  // a segment with candidates around the node
  thread_local std::vector<std::uint8_t> pierced, blocked_edge, blocked_node, near_node;
  seg.assign(ne, Nearest{});
  if (hint->size() != static_cast<std::size_t>(nn) + ne) hint->assign(nn + ne, -1);
  if (seg_tris.size() < ne) seg_tris.resize(ne);
  node_seg.assign(static_cast<std::size_t>(nn), -1);
  pierced.assign(ne, 0);
  blocked_edge.assign(ne, 0);
  blocked_node.assign(static_cast<std::size_t>(nn), 0);
  near_node.assign(static_cast<std::size_t>(nn), 0);
  // Segments: piercings (a stitch passes through the surface there) and candidates.
  thread_local std::vector<std::int32_t> run_tris;
  std::size_t run_of = ne;  // run whose union query run_tris holds
  for (std::size_t i = 0; i < ne; ++i) {
    const std::int32_t a = tm.initial.edges[i][0], b = tm.initial.edges[i][1];
    if (!B->ThreadAlive(thread, a) || !B->ThreadAlive(thread, b)) continue;
    const Simplex sg = SegmentSimplex(x.col(a), x.col(b));
    const Box sbox = SimplexBox(sg);
    const Box q = sbox.Inflated(reach);
    if (!q.Overlaps(bounds)) continue;
    std::vector<std::int32_t>& st = seg_tris[i];
    if (batch) {
      // One tree query per run of kRun segments (their boxes' union), filtered per segment:
      // the same ascending list as a query with q, for a fraction of the traversals.
      if (i / kRun != run_of) {
        run_of = i / kRun;
        Box u;
        for (std::size_t j = run_of * kRun; j < std::min(ne, (run_of + 1) * kRun); ++j) {
          const std::int32_t ja = tm.initial.edges[j][0], jb = tm.initial.edges[j][1];
          if (!B->ThreadAlive(thread, ja) || !B->ThreadAlive(thread, jb)) continue;
          u.Add(x.col(ja));
          u.Add(x.col(jb));
        }
        run_tris.clear();
        bvh.Query(u.Inflated(reach), &run_tris);
      }
      st.clear();
      for (std::int32_t t : run_tris) {
        if (bvh.TriangleBox(t).Overlaps(q)) st.push_back(t);
      }
    } else {
      query(static_cast<std::size_t>(nn) + i, q, &st);
    }
    if (st.empty()) continue;
    seg[i] = NearestOnSurface(sg, sbox, st, bvh, pos, s.local_tris, (*hint)[nn + i]);
    if (!seg[i].found) continue;
    (*hint)[nn + i] = seg[i].tri;
    near_node[a] = near_node[b] = 1;
    if (node_seg[a] < 0) node_seg[a] = static_cast<std::int32_t>(i);
    if (node_seg[b] < 0) node_seg[b] = static_cast<std::int32_t>(i);
    if (seg[i].pair.dist2 == 0) pierced[i] = 1;
  }
  // Next to a piercing the thread enters the tissue on purpose: no contacts there.
  for (std::size_t i = 0; i < ne; ++i) {
    if (!pierced[i]) continue;
    for (std::size_t j = i > 0 ? i - 1 : 0; j <= i + 1 && j < ne; ++j) blocked_edge[j] = 1;
  }
  for (std::size_t i = 0; i < ne; ++i) {
    if (blocked_edge[i])
      blocked_node[tm.initial.edges[i][0]] = blocked_node[tm.initial.edges[i][1]] = 1;
  }
  // Nodes.
  for (Eigen::Index v = 0; v < nn; ++v) {
    const std::int32_t node = static_cast<std::int32_t>(v);
    if (!near_node[v] || blocked_node[v] || !B->ThreadAlive(thread, node) ||
        B->ThreadFixed(thread, node)) {
      continue;
    }
    const Simplex p = PointSimplex(x.col(v));
    const Box pbox = SimplexBox(p);
    // The node's query box lies inside its segment's: filtering that segment's candidates gives
    // exactly the triangles a query would (same overlap test, ascending).
    const Box q = pbox.Inflated(reach);
    tris.clear();
    for (std::int32_t t : seg_tris[node_seg[v]]) {
      if (bvh.TriangleBox(t).Overlaps(q)) tris.push_back(t);
    }
    const Nearest n = NearestOnSurface(p, pbox, tris, bvh, pos, s.local_tris, (*hint)[v]);
    if (n.found) (*hint)[v] = n.tri;
    if (!n.found || !in_contact(n)) continue;
    ThreadSurfaceContact(B, thread, ThreadPoint(thread, node, node, 0.0), n, obstacle,
                         obstacle_index, s, rt, stiffness);
  }
  // Segment interiors (a thread over an edge of the surface).
  for (std::size_t i = 0; i < ne; ++i) {
    const Nearest& n = seg[i];
    const double u = n.pair.wa[1];
    if (!n.found || blocked_edge[i] || u <= 1e-9 || u >= 1 - 1e-9 || !in_contact(n)) continue;
    // Only where the segment dips below its end nodes' distances (a real interior minimum).
    const std::int32_t a = tm.initial.edges[i][0], b = tm.initial.edges[i][1];
    if (B->ThreadFixed(thread, a) && B->ThreadFixed(thread, b)) continue;
    const double da =
        std::sqrt(Closest(PointSimplex(x.col(a)),
                          TriangleSimplex(pos[s.local_tris[n.tri][0]], pos[s.local_tris[n.tri][1]],
                                          pos[s.local_tris[n.tri][2]]))
                      .dist2);
    const double db =
        std::sqrt(Closest(PointSimplex(x.col(b)),
                          TriangleSimplex(pos[s.local_tris[n.tri][0]], pos[s.local_tris[n.tri][1]],
                                          pos[s.local_tris[n.tri][2]]))
                      .dist2);
    if (n.dist >= std::min(da, db) - 1e-9) continue;
    ThreadSurfaceContact(B, thread, ThreadPoint(thread, a, b, u), n, obstacle, obstacle_index, s,
                         rt, stiffness);
  }
}

// ---- soft tissue against bone -----------------------------------------------------------------

// Bone triangles whose box overlaps `query`, ascending, through entry i of *cache: its list was
// made for a wider box and is refreshed when `query` leaves it or the bone changed.
constexpr double kNearBoneSlack = 0.5;  // mm; soft tissue and threads move far less per step

void NearBoneTriangles(const CollisionWorld::BoneEntry& g, NearBoneCache* cache, std::size_t i,
                       const Box& query, std::vector<std::int32_t>* out) {
  out->clear();
  const Box& w = cache->wide[i];
  if (!cache->valid[i] || (query.lo.array() < w.lo.array()).any() ||
      (query.hi.array() > w.hi.array()).any()) {
    std::vector<std::int32_t>& list = cache->tris[i];
    list.clear();
    cache->wide[i] = query.Inflated(kNearBoneSlack);
    g.bvh.Query(cache->wide[i], &list);
    cache->valid[i] = 1;
  }
  for (std::int32_t t : cache->tris[i]) {
    if (g.bvh.TriangleBox(t).Overlaps(query)) out->push_back(t);
  }
}

// After NearBoneTriangles(g, cache, i, query, ...): a lower bound of the distance from `from` (a
// point inside `query`) to every bone triangle it left out (mm): the nearest left-out box in the
// list, or the wide box's faces, beyond which no unlisted triangle lies.
double LeftOutLowerBound(const CollisionWorld::BoneEntry& g, const NearBoneCache& cache,
                         std::size_t i, const Box& query, const Vec3& from) {
  const Box& w = cache.wide[i];
  const Box at{from, from};
  double lower2 = std::pow(std::min((w.hi - from).minCoeff(), (from - w.lo).minCoeff()), 2);
  for (std::int32_t t : cache.tris[i]) {
    const Box& b = g.bvh.TriangleBox(t);
    if (!b.Overlaps(query)) lower2 = std::min(lower2, BoxDist2(at, b));
  }
  return std::sqrt(lower2);
}

void ResetNearBone(std::int64_t version, std::size_t slots, NearBoneCache* cache) {
  if (cache->bone_version == version && cache->wide.size() == slots) return;
  cache->bone_version = version;
  cache->wide.assign(slots, Box{});
  cache->valid.assign(slots, 0);
  cache->tris.assign(slots, {});
  cache->far_at.assign(slots, Vec3::Zero());
  cache->far_margin.assign(slots, -1.0);
  cache->hint.assign(slots, -1);
}

// True if every undirected edge of the triangles is shared by exactly two of them.
bool ClosedSurface(const std::vector<mesh::Tri>& tris) {
  std::vector<std::pair<std::int32_t, std::int32_t>> edges;
  edges.reserve(3 * tris.size());
  for (const mesh::Tri& t : tris) {
    for (int k = 0; k < 3; ++k) {
      edges.emplace_back(std::min(t[k], t[(k + 1) % 3]), std::max(t[k], t[(k + 1) % 3]));
    }
  }
  std::sort(edges.begin(), edges.end());
  for (std::size_t i = 0; i < edges.size(); i += 2) {
    if (i + 1 >= edges.size() || edges[i] != edges[i + 1] ||
        (i + 2 < edges.size() && edges[i + 2] == edges[i])) {
      return false;
    }
  }
  return !edges.empty();
}

void TissueBone(Builder* B, int body, CollisionWorld::SoftEntry& s, int bone,
                CollisionWorld::BoneEntry& g) {
  const CollisionParams& P = B->params;
  if (s.bvh.empty() || g.bvh.empty()) return;
  const double margin = std::max(P.alarm_distance_mm, P.max_depth_mm);
  if (!s.bvh.Bounds().Inflated(margin + kNearBoneSlack).Overlaps(g.bvh.Bounds())) return;
  NearBoneCache& cache = s.near_bone[bone];
  ResetNearBone(g.version, s.positions.size(), &cache);
  thread_local std::vector<std::int32_t> cand;
  for (std::size_t vi = 0; vi < s.positions.size(); ++vi) {
    const std::int32_t v = static_cast<std::int32_t>(vi);
    const std::int32_t node = s.surface.vertices[v];
    if (s.fixed[vi]) continue;
    const Vec3& p = s.positions[v];
    // Still within the bound of an earlier search that found it clearly out of contact: the
    // same search now would too (no contact; the candidate cache is only a shortcut).
    if (cache.far_margin[vi] > 0 && (p - cache.far_at[vi]).norm() < cache.far_margin[vi]) continue;
    cache.far_margin[vi] = -1;
    const Box query{p.array() - margin, p.array() + margin};
    NearBoneTriangles(g, &cache, vi, query, &cand);
    const Nearest n = cand.empty()
                          ? Nearest{}
                          : NearestOnSurface(PointSimplex(p), Box{p, p}, cand, g.bvh, g.positions,
                                             g.indexed.local_tris, cache.hint[vi]);
    if (n.found) cache.hint[vi] = n.tri;
    const double sd = n.found ? n.Signed() : margin;
    if (!n.found || (sd >= 0 ? sd >= P.alarm_distance_mm : -sd >= P.max_depth_mm)) {
      // No contact. The unsigned distance to the bone is at least `lower`; while the vertex
      // moves less than lower - margin it stays beyond both contact ranges (alarm outside,
      // max depth inside), so every search would find no contact.
      const double rest = LeftOutLowerBound(g, cache, vi, query, p);  // triangles not searched
      const double lower = n.found ? std::min(n.dist, rest) : rest;
      double bound = lower - margin - kCertSlack;
      // Outside a closed surface within `margin` (so the search saw every triangle that near
      // and the sign is exact), the signed distance is 1-Lipschitz: after moving less than
      // sd - alarm the vertex is still out of reach. (Around the rim of an open surface the
      // sign may flip; beyond `margin` the search only bounds the distance from above.)
      if (n.found && g.closed && sd < margin) {
        bound = std::max(bound, sd - P.alarm_distance_mm - kCertSlack);
      }
      if (bound > 0) {
        cache.far_at[vi] = p;
        cache.far_margin[vi] = bound;
      }
      continue;
    }
    PointContact c;
    c.target = PointContact::Target::kSoftBody;
    c.index = body;
    c.nodes = {node, -1, -1, -1};
    c.weights = {1, 0, 0, 0};
    c.normal = sd > kMinDirection ? Vec3((n.pair.pa - n.pair.pb) / n.dist) : n.pseudo;
    c.offset_mm = c.normal.dot(n.pair.pb) + P.contact_distance_mm;
    c.stiffness_n_per_mm = P.bone_stiffness_n_per_mm;
    c.obstacle_id = bone;
    B->Add(c, Kind::kBone);
  }
}

// ---- soft tissue against soft tissue (different bodies) ------------------------------------

// Surface vertices of body a near the surface of body b: contact on both sides, as for a thread
// on tissue (vertex of a along +n, the nearest point of b's triangle along -n; n out of b).
// Called for both orders of a pair, so each side's vertices meet the other's triangles. Joined
// bodies: vertices near the join at rest and triangles touching a joined node are left out (the
// interface is inside the merged body).
void TissueTissue(Builder* B, int a, CollisionWorld::SoftEntry& ea, int b,
                  const CollisionWorld::SoftEntry& eb) {
  const CollisionParams& P = B->params;
  if (ea.bvh.empty() || eb.bvh.empty()) return;
  const double reach = std::max(P.alarm_distance_mm, P.max_depth_mm);
  const Box bounds = eb.bvh.Bounds();
  if (!ea.bvh.Bounds().Inflated(reach).Overlaps(bounds)) return;
  const std::vector<std::uint8_t>* skip_v =
      static_cast<std::size_t>(b) < ea.join_vertex.size() && !ea.join_vertex[b].empty()
          ? &ea.join_vertex[b]
          : nullptr;
  const std::vector<std::uint8_t>* skip_t =
      static_cast<std::size_t>(a) < eb.join_tri.size() && !eb.join_tri[a].empty() ? &eb.join_tri[a]
                                                                                  : nullptr;
  FarBounds& far = ea.far_soft[b];
  far.Reset(ea.version, eb.version, ea.positions.size());
  // Searched out to `wide`: a vertex found farther than reach keeps the difference as a bound.
  const double wide = reach + kFarSlack;
  thread_local std::vector<std::int32_t> cand;
  for (std::size_t vi = 0; vi < ea.positions.size(); ++vi) {
    if (skip_v != nullptr && (*skip_v)[vi]) continue;
    const Vec3& p = ea.positions[vi];
    if (far.Holds(vi, p, eb.drift_mm)) continue;
    far.margin[vi] = -1;
    // Lower bound of the distance to b's surface: the searched box, or the nearest triangle.
    double lower = wide;
    Nearest n;
    if (NearBoxes(Box{p, p}, wide, bounds)) {
      cand.clear();
      eb.bvh.Query(Box{p.array() - wide, p.array() + wide}, &cand);
      if (skip_t != nullptr) {
        cand.erase(std::remove_if(cand.begin(), cand.end(),
                                  [&](std::int32_t t) { return (*skip_t)[t] != 0; }),
                   cand.end());
      }
      n = NearestOnSurface(PointSimplex(p), Box{p, p}, cand, eb.bvh, eb.positions,
                           eb.surface.local_tris);
      if (n.found) lower = std::min(lower, n.dist);
    } else {
      lower = std::max(wide, std::sqrt(BoxDist2(Box{p, p}, bounds)));
    }
    if (lower >= reach) {  // |signed distance| >= reach: no contact either side of the surface
      far.at[vi] = p;
      far.margin[vi] = lower - reach - kCertSlack;
      far.drift0[vi] = eb.drift_mm;
      continue;
    }
    const double sd = n.Signed();
    if (sd >= 0 ? sd >= P.alarm_distance_mm : -sd >= P.max_depth_mm) continue;
    const Vec3 normal = sd > kMinDirection ? Vec3((n.pair.pa - n.pair.pb) / n.dist) : n.pseudo;
    // Both sides move: each plane is half-way, so that two stiff responses meet at the skin
    // distance instead of each jumping to the other's old place (which overshoots by the
    // penetration and rings). A side that cannot move (all fixed) leaves the whole gap to the
    // other.
    const mesh::Tri& g = eb.surface.tris[n.tri];
    const bool a_moves = !ea.fixed[vi];
    const bool b_moves = !(B->SoftFixed(b, g[0]) && B->SoftFixed(b, g[1]) && B->SoftFixed(b, g[2]));
    const double ha = normal.dot(n.pair.pa), hb = normal.dot(n.pair.pb);
    const double mid = 0.5 * (ha + hb), skin = P.contact_distance_mm;
    if (a_moves) {
      PointContact c;
      c.target = PointContact::Target::kSoftBody;
      c.index = a;
      c.nodes = {ea.surface.vertices[vi], -1, -1, -1};
      c.weights = {1, 0, 0, 0};
      c.normal = normal;
      c.offset_mm = b_moves ? mid + 0.5 * skin : hb + skin;
      c.stiffness_n_per_mm = P.tissue_tissue_stiffness_n_per_mm;
      c.obstacle_id = b;
      B->Add(c, Kind::kSoftBody);
    }
    if (b_moves) {
      PointContact t;
      t.target = PointContact::Target::kSoftBody;
      t.index = b;
      t.nodes = {g[0], g[1], g[2], -1};
      t.weights = {n.pair.wb[0], n.pair.wb[1], n.pair.wb[2], 0};
      t.normal = -normal;
      t.offset_mm = a_moves ? -mid + 0.5 * skin : -ha + skin;
      t.stiffness_n_per_mm = P.tissue_tissue_stiffness_n_per_mm;
      t.obstacle_id = a;
      B->Add(t, Kind::kSoftBody);
    }
  }
}

// ---- salient bone vertices against soft triangles ---------------------------------------------

// A bone corner (spur tip) near or inside a soft surface whose nearest soft point is inside a
// triangle or on an edge (at a soft vertex, tissue-bone already holds it): that soft point is
// pushed away from the corner, to contact_distance beyond it along the soft surface normal.
void BoneTipTissue(Builder* B, int body, const CollisionWorld::SoftEntry& s, int bone,
                   CollisionWorld::BoneEntry& g) {
  const CollisionParams& P = B->params;
  if (s.bvh.empty() || g.salient.empty()) return;
  const double reach = std::max(P.alarm_distance_mm, P.max_depth_mm);
  const double wide = reach + kFarSlack;
  const Box bounds = s.bvh.Bounds();
  FarBounds& far = g.far_soft[body];
  far.Reset(g.version, s.version, g.salient.size());
  thread_local std::vector<std::int32_t> cand;
  for (std::size_t i = 0; i < g.salient.size(); ++i) {
    const Vec3& p = g.positions[g.salient[i]];
    if (far.Holds(i, p, s.drift_mm)) continue;
    far.margin[i] = -1;
    double lower = wide;
    Nearest n;
    if (NearBoxes(Box{p, p}, wide, bounds)) {
      cand.clear();
      s.bvh.Query(Box{p.array() - wide, p.array() + wide}, &cand);
      n = NearestOnSurface(PointSimplex(p), Box{p, p}, cand, s.bvh, s.positions,
                           s.surface.local_tris);
      if (n.found) lower = std::min(lower, n.dist);
    } else {
      lower = std::max(wide, std::sqrt(BoxDist2(Box{p, p}, bounds)));
    }
    if (lower >= reach) {
      far.at[i] = p;
      far.margin[i] = lower - reach - kCertSlack;
      far.drift0[i] = s.drift_mm;
      continue;
    }
    const double sd = n.Signed();  // of the bone corner from the soft surface
    if (sd >= 0 ? sd >= P.alarm_distance_mm : -sd >= P.max_depth_mm) continue;
    const auto& w = n.pair.wb;
    if ((w[0] <= 0) + (w[1] <= 0) + (w[2] <= 0) >= 2) continue;  // at a soft vertex
    const mesh::Tri& t = s.surface.tris[n.tri];
    if (B->SoftFixed(body, t[0]) && B->SoftFixed(body, t[1]) && B->SoftFixed(body, t[2])) continue;
    // n: out of the tissue toward the corner; the tissue point must stay behind the corner.
    const Vec3 normal = sd > kMinDirection ? Vec3((n.pair.pa - n.pair.pb) / n.dist) : n.pseudo;
    PointContact c;
    c.target = PointContact::Target::kSoftBody;
    c.index = body;
    c.nodes = {t[0], t[1], t[2], -1};
    c.weights = {w[0], w[1], w[2], 0};
    c.normal = -normal;
    c.offset_mm = -normal.dot(p) + P.contact_distance_mm;
    c.stiffness_n_per_mm = P.bone_stiffness_n_per_mm;
    c.obstacle_id = bone;
    B->Add(c, Kind::kBone);
  }
}

// A bone vertex is salient when it sticks out of its neighbours' plane at a corner sharper than
// kSalientDeg between the vertex normal and an adjacent face normal: a smooth tessellated
// surface (the humeral head: ~4 degrees between faces) has none, a spur tip does. Below that,
// a tissue triangle lying on the bone is at most a sagitta L^2 / 8R away, under the skin.
constexpr double kSalientDeg = 20.0;

std::vector<std::int32_t> SalientVertices(const Surface& s, const std::vector<Vec3>& p) {
  std::vector<std::int32_t> out;
  const double cos_lim = std::cos(kSalientDeg * 3.14159265358979323846 / 180.0);
  for (std::size_t vi = 0; vi < p.size(); ++vi) {
    const std::int32_t v = static_cast<std::int32_t>(vi);
    const Vec3 vn = VertexNormal(s, p, v);
    Vec3 ring = Vec3::Zero();
    int count = 0;
    bool sharp = false;
    for (std::int32_t k = s.vertex_tri_start[v]; k < s.vertex_tri_start[v + 1]; ++k) {
      const mesh::Tri& t = s.local_tris[s.vertex_tris[k]];
      if (FaceNormal(p, t).dot(vn) < cos_lim) sharp = true;
      for (std::int32_t u : t) {
        if (u == v) continue;
        ring += p[u];
        ++count;
      }
    }
    // Convex: the vertex lies outside its neighbours' mean (a crease or pit cannot poke).
    if (sharp && count > 0 && vn.dot(p[v] - ring / count) > 0) out.push_back(v);
  }
  return out;
}

// Join flags of body b's surface against every soft body joined to it (CollisionWorld::SoftEntry
// join_vertex / join_tri): joined nodes are those coincident at rest within the join tolerance
// (as physics merges them); vertices within `band` mm of one at rest are near the join.
void JoinFlags(const Model& model, const State& state, std::size_t b, double band,
               CollisionWorld::SoftEntry* e) {
  const std::size_t nb = state.soft_bodies.size();
  e->join_vertex.assign(nb, {});
  e->join_tri.assign(nb, {});
  if (b >= model.soft_bodies.size()) return;
  const Points& xa = model.soft_bodies[b].rest_mesh.nodes;
  for (const Join& join : model.joins) {
    const int ia = model.FindSoftBody(join.body_a), ib = model.FindSoftBody(join.body_b);
    if (ia < 0 || ib < 0 || ia == ib) continue;
    const int other =
        static_cast<std::size_t>(ia) == b ? ib : (static_cast<std::size_t>(ib) == b ? ia : -1);
    if (other < 0 || static_cast<std::size_t>(other) >= nb) continue;
    const Points& xo = model.soft_bodies[other].rest_mesh.nodes;
    // Joined nodes of b: coincident with a node of `other` (sorted by x, then a window).
    std::vector<std::pair<double, std::int32_t>> sorted;
    sorted.reserve(static_cast<std::size_t>(xo.cols()));
    for (Eigen::Index k = 0; k < xo.cols(); ++k)
      sorted.emplace_back(xo(0, k), static_cast<std::int32_t>(k));
    std::sort(sorted.begin(), sorted.end());
    const double tol = join.tolerance_mm;
    std::vector<std::uint8_t> joined(static_cast<std::size_t>(xa.cols()), 0);
    std::vector<Vec3> joined_at;
    for (Eigen::Index i = 0; i < xa.cols(); ++i) {
      const Vec3 p = xa.col(i);
      auto it = std::lower_bound(sorted.begin(), sorted.end(),
                                 std::make_pair(p.x() - tol, std::int32_t{-1}));
      for (; it != sorted.end() && it->first <= p.x() + tol; ++it) {
        if ((Vec3(xo.col(it->second)) - p).norm() <= tol) {
          joined[static_cast<std::size_t>(i)] = 1;
          joined_at.push_back(p);
          break;
        }
      }
    }
    if (joined_at.empty()) continue;
    auto is_joined = [&](std::int32_t node) {
      return node >= 0 && node < static_cast<std::int32_t>(joined.size()) && joined[node] != 0;
    };
    std::vector<std::uint8_t>& jv = e->join_vertex[other];
    jv.assign(e->surface.vertices.size(), 0);
    const Points& rest = state.soft_bodies[b].x_rest;
    for (std::size_t v = 0; v < jv.size(); ++v) {
      const std::int32_t node = e->surface.vertices[v];
      const Vec3 p = node < xa.cols()
                         ? Vec3(xa.col(node))
                         : (node < rest.cols() ? Vec3(rest.col(node)) : Vec3(e->positions[v]));
      for (const Vec3& q : joined_at) {
        if ((p - q).squaredNorm() < band * band) {
          jv[v] = 1;
          break;
        }
      }
    }
    std::vector<std::uint8_t>& jt = e->join_tri[other];
    jt.assign(e->surface.tris.size(), 0);
    for (std::size_t t = 0; t < jt.size(); ++t) {
      const mesh::Tri& g = e->surface.tris[t];
      jt[t] = is_joined(g[0]) || is_joined(g[1]) || is_joined(g[2]) ? 1 : 0;
    }
  }
}

// Fills the first entries of *sweeps (reusing their storage) with the swept contact parts of one
// tool slot and returns how many; *prims and *before receive this step's and last step's
// primitives (sweeps point into *prims).
std::size_t MakeSweeps(const Model& model, const ToolState& prev, const ToolState& cur,
                       const CollisionParams& params, std::vector<ToolPrimitive>* prims,
                       std::vector<ToolPrimitive>* before, std::vector<Sweep>* sweeps,
                       std::int32_t* substeps) {
  ToolPrimitivesWorld(model, cur, prims);
  if (prev.instrument == cur.instrument) {
    ToolPrimitivesWorld(model, prev, before);
  } else {
    before->assign(prims->begin(), prims->end());
  }
  double disp = 0;
  for (std::size_t j = 0; j < prims->size(); ++j) {
    for (int i = 0; i < (*prims)[j].core.n; ++i) {
      disp = std::max(disp, ((*prims)[j].core.v[i] - (*before)[j].core.v[i]).norm());
    }
  }
  const double step = params.sweep_fraction * params.alarm_distance_mm;
  const int k = std::clamp(static_cast<int>(std::ceil(disp / step)), 1, params.max_substeps);
  *substeps = k;
  std::size_t used = 0;
  for (std::size_t j = 0; j < prims->size(); ++j) {
    if (!(*prims)[j].contacts) continue;
    if (sweeps->size() <= used) {
      sweeps->emplace_back();  // sized once for the largest substep count
      sweeps->back().sub.reserve(static_cast<std::size_t>(params.max_substeps) + 1);
      sweeps->back().sub_box.reserve(static_cast<std::size_t>(params.max_substeps) + 1);
    }
    Sweep& sw = (*sweeps)[used++];
    sw.prim = &(*prims)[j];
    sw.sub.clear();
    sw.sub_box.clear();
    sw.box = Box{};
    for (int s = 0; s <= k; ++s) {
      Simplex core = (*prims)[j].core;
      if (s < k) {
        const double f = static_cast<double>(s) / k;
        for (int i = 0; i < core.n; ++i) {
          core.v[i] = (*before)[j].core.v[i] + f * ((*prims)[j].core.v[i] - (*before)[j].core.v[i]);
        }
      }
      Box cb;
      for (int i = 0; i < core.n; ++i) cb.Add(core.v[i]);
      sw.box.Add(cb.lo);
      sw.box.Add(cb.hi);
      sw.sub.push_back(core);
      sw.sub_box.push_back(cb);
    }
  }
  // Entries past `used` are kept (with their storage) for later steps, not destroyed.
  return used;
}

// Everything one tool slot touches this step: tissue (surface and volume), threads, bones (the
// reaction goes to out->bone_force_n[slot], the touches to *touches).
void DetectToolSlot(Builder* B, int slot, const std::array<ToolState, kToolSlots>& prev_tools,
                    CollisionWorld* world, const std::vector<ThreadBoxes>& thread_boxes,
                    CollisionOutput* out, std::vector<ToolContact>* touches) {
  const Model& model = B->model;
  const State& state = B->state;
  thread_local std::array<std::vector<ToolPrimitive>, kToolSlots> prims, before;
  thread_local std::array<std::vector<Sweep>, kToolSlots> slot_sweeps;
  out->substeps[slot] = 0;
  const std::size_t used =
      MakeSweeps(model, prev_tools[slot], state.tools[slot], B->params, &prims[slot], &before[slot],
                 &slot_sweeps[slot], &out->substeps[slot]);
  const std::span<const Sweep> sweeps(slot_sweeps[slot].data(), used);
  for (std::size_t b = 0; b < world->soft.size(); ++b) {
    for (const Sweep& sw : sweeps) {
      ToolTissue(B, slot, sw, static_cast<int>(b), world->soft[b]);
      ToolVolume(B, slot, sw, static_cast<int>(b), state.soft_bodies[b], world->soft[b]);
    }
  }
  if (!sweeps.empty()) {
    for (std::size_t t = 0; t < state.threads.size(); ++t) {
      for (const Sweep& sw : sweeps) ToolThread(B, slot, sw, static_cast<int>(t), thread_boxes[t]);
    }
  }
  for (std::size_t g = 0; g < world->bones.size(); ++g) {
    double deepest = 0;
    Vec3 point = Vec3::Zero();
    for (const Sweep& sw : sweeps) {
      ToolBone(B, slot, sw, world->bones[g], out, &deepest, &point);
    }
    if (deepest > 0) touches->push_back(ToolContact{slot, Kind::kBone, static_cast<int>(g), point});
  }
}

// One thread against every soft surface (both sides) and bone (thread side).
void DetectThread(Builder* B, int t, CollisionWorld* world) {
  const CollisionParams& params = B->params;
  for (std::size_t b = 0; b < world->soft.size(); ++b) {
    const auto& e = world->soft[b];
    ThreadSurface(B, t, Kind::kSoftBody, static_cast<int>(b), e.surface, e.positions, e.bvh,
                  params.thread_tissue_stiffness_n_per_mm, true, &world->threads[t].soft_hint[b],
                  [&](std::size_t, const Box& q, std::vector<std::int32_t>* out) {
                    out->clear();
                    e.bvh.Query(q, out);
                  });
  }
  for (std::size_t g = 0; g < world->bones.size(); ++g) {
    const auto& e = world->bones[g];
    NearBoneCache& cache = world->threads[t].near_bone[g];
    const std::size_t slots = static_cast<std::size_t>(B->state.threads[t].x.cols()) +
                              B->model.threads[t].initial.edges.size();
    ResetNearBone(e.version, slots, &cache);
    ThreadSurface(B, t, Kind::kBone, static_cast<int>(g), e.indexed, e.positions, e.bvh,
                  params.bone_stiffness_n_per_mm, false, &cache.hint,
                  [&](std::size_t i, const Box& q, std::vector<std::int32_t>* out) {
                    NearBoneTriangles(e, &cache, i, q, out);
                  });
  }
}

}  // namespace

void SyncWorld(const Model& model, const State& state, CollisionWorld* world) {
  world->soft.resize(state.soft_bodies.size());
  for (std::size_t b = 0; b < state.soft_bodies.size(); ++b) {
    const SoftBodyState& sb = state.soft_bodies[b];
    CollisionWorld::SoftEntry& e = world->soft[b];
    if (!e.built || e.tet_count != sb.tets.size() || e.alive != sb.tet_alive) {
      e.surface = MakeSurface(BoundaryTriangles(sb.tets, sb.tet_alive));
      e.tet_count = sb.tets.size();
      e.alive = sb.tet_alive;
      FillPositions(sb.x, e.surface.vertices, &e.positions);
      e.bvh.Build(e.positions, e.surface.local_tris);
      e.built = true;
      e.near_bone.clear();
      e.fixed.assign(e.surface.vertices.size(), 0);
      if (b < model.soft_bodies.size()) {
        const auto& f = model.soft_bodies[b].fixed_nodes;
        for (std::size_t v = 0; v < e.surface.vertices.size(); ++v) {
          e.fixed[v] = std::binary_search(f.begin(), f.end(), e.surface.vertices[v]) ? 1 : 0;
        }
      }
      JoinFlags(model, state, b, model.contact.alarm_distance_mm + model.contact.max_depth_mm, &e);
      ++e.version;
      e.drift_mm = 0;
      ++world->rebuilds;
      e.refit_pending = false;
    } else {
      e.refit_pending = true;
    }
  }
  // Refit the others, and each surface's drift (largest vertex move) for the out-of-reach
  // bounds: independent per body.
  ParallelFor(static_cast<std::int64_t>(state.soft_bodies.size()), 1,
              [&](std::int64_t begin, std::int64_t end) {
                for (std::int64_t b = begin; b < end; ++b) {
                  CollisionWorld::SoftEntry& e = world->soft[static_cast<std::size_t>(b)];
                  if (!e.refit_pending) continue;
                  const Points& x = state.soft_bodies[static_cast<std::size_t>(b)].x;
                  double move2 = 0;
                  for (std::size_t i = 0; i < e.surface.vertices.size(); ++i) {
                    const Vec3 q = x.col(e.surface.vertices[i]);
                    move2 = std::max(move2, (q - e.positions[i]).squaredNorm());
                    e.positions[i] = q;
                  }
                  e.drift_mm += std::sqrt(move2);
                  e.bvh.Refit(e.positions);
                  e.refit_pending = false;
                }
              });
  world->bones.resize(state.bones.size());
  for (std::size_t g = 0; g < state.bones.size(); ++g) {
    const mesh::TriMesh& m = state.bones[g].surface;
    CollisionWorld::BoneEntry& e = world->bones[g];
    // Bone surfaces change only through code that increments their revision; the sizes are a
    // cheap second check. (A bitwise comparison of both surfaces cost ~10% of the stage.)
    const bool same = e.built && e.revision == state.bones[g].revision &&
                      e.surface.nodes.cols() == m.nodes.cols() &&
                      e.surface.tris.size() == m.tris.size();
    if (same) continue;
    e.revision = state.bones[g].revision;
    e.surface = m;
    e.indexed = MakeSurface(CanonicalTriangles(m.tris));
    FillPositions(m.nodes, e.indexed.vertices, &e.positions);
    e.bvh.Build(e.positions, e.indexed.local_tris);
    e.closed = ClosedSurface(e.indexed.tris);
    e.salient = SalientVertices(e.indexed, e.positions);
    e.built = true;
    ++e.version;
    ++world->rebuilds;
  }
  for (CollisionWorld::SoftEntry& e : world->soft) {
    e.near_bone.resize(world->bones.size());
    e.far_soft.resize(world->soft.size());
  }
  for (CollisionWorld::BoneEntry& e : world->bones) e.far_soft.resize(world->soft.size());
  world->threads.resize(state.threads.size());
  for (CollisionWorld::ThreadEntry& e : world->threads) {
    e.near_bone.resize(world->bones.size());
    e.soft_hint.resize(world->soft.size());
  }
}

void Detect(const Model& model, const State& state,
            const std::array<ToolState, kToolSlots>& prev_tools, const CollisionParams& params,
            CollisionWorld* world, CollisionOutput* out) {
  SyncWorld(model, state, world);
  out->bone_force_n.fill(Vec3::Zero());
  out->bone_touches.clear();
  // Thread segment boxes for the tool tests, shared by both slots.
  thread_local std::vector<ThreadBoxes> thread_boxes;
  if (thread_boxes.size() < state.threads.size()) thread_boxes.resize(state.threads.size());
  bool tool_in = false;
  for (const ToolState& t : state.tools) tool_in = tool_in || t.instrument >= 0;
  if (tool_in) {
    for (std::size_t t = 0; t < state.threads.size(); ++t) {
      MakeThreadBoxes(model, state, static_cast<int>(t), &thread_boxes[t]);
    }
  }
  // Independent tasks, in the order the contacts would be created one after the other: tool
  // slots, threads (against tissue and bone), soft bodies (against bones), soft bodies (against
  // other soft bodies). Each task writes its own lists and only world data no other task reads
  // or writes (its slot's sweeps and bone force, its thread's caches, its body's caches), so
  // the merged lists are the same for any thread count and any order of completion.
  const std::size_t nthreads = state.threads.size(), nsoft = world->soft.size();
  const std::size_t tissue_tasks = params.tissue_tissue_contacts ? nsoft : 0;
  const std::size_t ntasks = kToolSlots + nthreads + nsoft + tissue_tasks;
  struct TaskOut {
    std::vector<PointContact> contacts;
    std::vector<Kind> kinds;
    std::vector<ToolContact> touches;
  };
  thread_local std::vector<TaskOut> task_scratch;  // kept across steps
  if (task_scratch.size() < ntasks) task_scratch.resize(ntasks);
  // Plain references: inside the task body a thread_local name would mean the worker's own.
  std::vector<TaskOut>& task_out = task_scratch;
  const std::vector<ThreadBoxes>& boxes = thread_boxes;
  auto run_task = [&](std::size_t task) {
    TaskOut& to = task_out[task];
    to.contacts.clear();
    to.kinds.clear();
    to.touches.clear();
    Builder B{model, state, params, to.contacts, to.kinds};
    if (task < static_cast<std::size_t>(kToolSlots)) {
      DetectToolSlot(&B, static_cast<int>(task), prev_tools, world, boxes, out, &to.touches);
      return;
    }
    task -= kToolSlots;
    if (task < nthreads) {
      DetectThread(&B, static_cast<int>(task), world);
      return;
    }
    task -= nthreads;
    if (task < nsoft) {
      for (std::size_t g = 0; g < world->bones.size(); ++g) {
        TissueBone(&B, static_cast<int>(task), world->soft[task], static_cast<int>(g),
                   world->bones[g]);
        if (params.bone_tip_contacts) {
          BoneTipTissue(&B, static_cast<int>(task), world->soft[task], static_cast<int>(g),
                        world->bones[g]);
        }
      }
      return;
    }
    task -= nsoft;
    for (std::size_t b = 0; b < nsoft; ++b) {
      if (b != task) {
        TissueTissue(&B, static_cast<int>(task), world->soft[task], static_cast<int>(b),
                     world->soft[b]);
      }
    }
  };
  ParallelFor(static_cast<std::int64_t>(ntasks), 1, [&](std::int64_t begin, std::int64_t end) {
    for (std::int64_t t = begin; t < end; ++t) run_task(static_cast<std::size_t>(t));
  });
  // Merged in task order (scratch kept across steps: no heap allocation in a steady state).
  thread_local std::vector<PointContact> scratch_contacts;
  thread_local std::vector<Kind> scratch_kinds;
  scratch_contacts.clear();
  scratch_kinds.clear();
  for (std::size_t t = 0; t < ntasks; ++t) {
    const TaskOut& to = task_out[t];
    scratch_contacts.insert(scratch_contacts.end(), to.contacts.begin(), to.contacts.end());
    scratch_kinds.insert(scratch_kinds.end(), to.kinds.begin(), to.kinds.end());
    out->bone_touches.insert(out->bone_touches.end(), to.touches.begin(), to.touches.end());
  }
  Builder B{model, state, params, scratch_contacts, scratch_kinds};
  // Creation order never matters: sort by (tool, target, body, obstacle, feature) and, for
  // completeness, by the remaining values.
  thread_local std::vector<std::size_t> order;
  order.resize(B.contacts.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  // Lexicographic on (tool, target, body, obstacle kind, obstacle, nodes, weights, offset,
  // normal, creation index), stopping at the first difference.
  auto less = [&](std::size_t i, std::size_t j) {
    const PointContact &a = B.contacts[i], &b = B.contacts[j];
    if (a.tool_slot != b.tool_slot) return a.tool_slot < b.tool_slot;
    if (a.target != b.target) return a.target < b.target;
    if (a.index != b.index) return a.index < b.index;
    if (B.kinds[i] != B.kinds[j]) return B.kinds[i] < B.kinds[j];
    if (a.obstacle_id != b.obstacle_id) return a.obstacle_id < b.obstacle_id;
    // Element by element (std::array's operators go through memcmp and a lexicographic compare).
    for (int k = 0; k < 4; ++k) {
      if (a.nodes[k] != b.nodes[k]) return a.nodes[k] < b.nodes[k];
    }
    for (int k = 0; k < 4; ++k) {
      if (a.weights[k] != b.weights[k]) return a.weights[k] < b.weights[k];
    }
    if (a.offset_mm != b.offset_mm) return a.offset_mm < b.offset_mm;
    for (int k = 0; k < 3; ++k) {
      if (a.normal[k] != b.normal[k]) return a.normal[k] < b.normal[k];
    }
    return i < j;  // creation order last: a total order, so an unstable sort is stable
  };
  // The leading fields (tool, target, body, obstacle kind, obstacle, first node) packed into one
  // integer whose order is theirs, so most comparisons are one integer compare; equal keys fall
  // back to the full comparison (same total order, so the same sorted list). Only used when
  // every field fits its bits.
  thread_local std::vector<std::uint64_t> key;
  key.resize(B.contacts.size());
  bool packed = true;
  for (std::size_t i = 0; i < B.contacts.size() && packed; ++i) {
    const PointContact& c = B.contacts[i];
    const std::uint64_t slot = static_cast<std::uint64_t>(c.tool_slot + 1);
    const std::uint64_t body = static_cast<std::uint64_t>(c.index);
    const std::uint64_t kind = static_cast<std::uint64_t>(B.kinds[i]);
    const std::uint64_t obst = static_cast<std::uint64_t>(c.obstacle_id + 1);
    const std::uint64_t node = static_cast<std::uint64_t>(c.nodes[0] + 1);
    packed = c.tool_slot >= -1 && slot < 4 && c.index >= 0 && body < 1024 && kind < 8 &&
             c.obstacle_id >= -1 && obst < 1024 && c.nodes[0] >= -1 && node < (1u << 21);
    key[i] = slot << 62 | static_cast<std::uint64_t>(c.target) << 61 | body << 51 | kind << 48 |
             obst << 38 | node << 17;
  }
  auto keyed_less = [&](std::size_t i, std::size_t j) {
    if (key[i] != key[j]) return key[i] < key[j];
    return less(i, j);
  };
  // Contacts are mostly created in order already: sort only when needed.
  if (packed) {
    if (!std::is_sorted(order.begin(), order.end(), keyed_less)) {
      std::sort(order.begin(), order.end(), keyed_less);  // in place: no buffer
    }
  } else if (!std::is_sorted(order.begin(), order.end(), less)) {
    std::sort(order.begin(), order.end(), less);
  }
  out->contacts.clear();
  out->obstacle_kind.clear();
  for (std::size_t i : order) {
    out->contacts.push_back(B.contacts[i]);
    out->obstacle_kind.push_back(B.kinds[i]);
  }
}

CollisionParams ParamsFromModel(const ContactOptions& c) {
  CollisionParams p;
  p.alarm_distance_mm = c.alarm_distance_mm;
  p.contact_distance_mm = c.contact_distance_mm;
  p.max_depth_mm = c.max_depth_mm;
  p.sweep_fraction = c.sweep_fraction;
  p.max_substeps = c.max_substeps;
  p.tool_tissue_stiffness_n_per_mm = c.tool_tissue_stiffness_n_per_mm;
  p.tool_thread_stiffness_n_per_mm = c.tool_thread_stiffness_n_per_mm;
  p.tool_volume_stiffness_n_per_mm = c.tool_volume_stiffness_n_per_mm;
  p.thread_tissue_stiffness_n_per_mm = c.thread_tissue_stiffness_n_per_mm;
  p.tissue_tissue_stiffness_n_per_mm = c.tissue_tissue_stiffness_n_per_mm;
  p.bone_stiffness_n_per_mm = c.bone_stiffness_n_per_mm;
  p.tool_bone_stiffness_n_per_mm = c.tool_bone_stiffness_n_per_mm;
  return p;
}

std::array<Vec3, kToolSlots> ToolForces(const CollisionOutput& out) {
  std::array<Vec3, kToolSlots> f = out.bone_force_n;
  for (const PointContact& c : out.contacts) {
    if (c.tool_slot >= 0 && c.tool_slot < kToolSlots) f[c.tool_slot] -= c.force_n * c.normal;
  }
  return f;
}

}  // namespace arthrosim::collision
