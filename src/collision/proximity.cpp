#include "arthrosim/collision/proximity.h"

#include "arthrosim/mesh/segment_closest.h"

#include <algorithm>
#include <cmath>

namespace arthrosim::collision {
namespace {

// Squared length below which an edge or a triangle's doubled area counts as degenerate (mm^2,
// mm^4 relative). Only exact or near-exact degeneracies reach it; 1e-12 mm is far below any
// mesh feature.
constexpr double kTinyLength2 = 1e-24;

double Clamp01(double x) { return std::clamp(x, 0.0, 1.0); }

ClosestPair Swapped(ClosestPair r) {
  std::swap(r.wa, r.wb);
  std::swap(r.pa, r.pb);
  return r;
}

ClosestPair Finish(ClosestPair r, const Simplex& a, const Simplex& b) {
  r.pa = a.At(r.wa);
  r.pb = b.At(r.wb);
  r.dist2 = (r.pa - r.pb).squaredNorm();
  return r;
}

}  // namespace

Vec3 Simplex::At(const std::array<double, 3>& w) const {
  Vec3 p = w[0] * v[0];
  if (n > 1) p += w[1] * v[1];
  if (n > 2) p += w[2] * v[2];
  return p;
}

Simplex PointSimplex(const Vec3& a) { return Simplex{1, {a, Vec3::Zero(), Vec3::Zero()}}; }
Simplex SegmentSimplex(const Vec3& a, const Vec3& b) { return Simplex{2, {a, b, Vec3::Zero()}}; }
Simplex TriangleSimplex(const Vec3& a, const Vec3& b, const Vec3& c) {
  return Simplex{3, {a, b, c}};
}

// The point with weights (w0, w1) on segment (a, b): Simplex::At's operations, without building
// simplices (same bits).
Vec3 SegmentAt(double w0, double w1, const Vec3& a, const Vec3& b) {
  Vec3 p = w0 * a;
  p += w1 * b;
  return p;
}

ClosestPair PointSegment(const Vec3& p, const Vec3& a, const Vec3& b) {
  const Vec3 ab = b - a;
  const double len2 = ab.dot(ab);
  const double t = len2 <= kTinyLength2 ? 0.0 : Clamp01((p - a).dot(ab) / len2);
  ClosestPair r;
  r.wa = {1, 0, 0};
  r.wb = {1.0 - t, t, 0};
  // As Finish(r, point, segment).
  r.pa = 1.0 * p;
  r.pb = SegmentAt(r.wb[0], r.wb[1], a, b);
  r.dist2 = (r.pa - r.pb).squaredNorm();
  return r;
}

ClosestPair PointTriangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 ab = b - a, ac = c - a;
  const double scale2 = std::max({ab.squaredNorm(), ac.squaredNorm(), (c - b).squaredNorm()});
  if (ab.cross(ac).squaredNorm() <= kTinyLength2 * std::max(scale2 * scale2, 1.0)) {
    // Degenerate (needle or point): the closest point is on one of its edges.
    ClosestPair best;
    best.dist2 = -1;
    const int edges[3][2] = {{0, 1}, {1, 2}, {2, 0}};
    for (const auto& e : edges) {
      const Vec3* v[3] = {&a, &b, &c};
      const ClosestPair s = PointSegment(p, *v[e[0]], *v[e[1]]);
      if (best.dist2 < 0 || s.dist2 < best.dist2) {
        best = s;
        best.wb = {0, 0, 0};
        best.wb[e[0]] = s.wb[0];
        best.wb[e[1]] += s.wb[1];
      }
    }
    return Finish(best, PointSimplex(p), TriangleSimplex(a, b, c));
  }
  // Voronoi regions of the vertices, edges and face; in a non-degenerate triangle the
  // denominators below are the squared edge lengths and the doubled area, all > 0.
  ClosestPair r;
  const Vec3 ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  const Vec3 bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  const Vec3 cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  const double vc = d1 * d4 - d3 * d2;
  const double vb = d5 * d2 - d1 * d6;
  const double va = d3 * d6 - d5 * d4;
  if (d1 <= 0 && d2 <= 0) {
    r.wb = {1, 0, 0};
  } else if (d3 >= 0 && d4 <= d3) {
    r.wb = {0, 1, 0};
  } else if (vc <= 0 && d1 >= 0 && d3 <= 0) {
    const double v = d1 / (d1 - d3);
    r.wb = {1 - v, v, 0};
  } else if (d6 >= 0 && d5 <= d6) {
    r.wb = {0, 0, 1};
  } else if (vb <= 0 && d2 >= 0 && d6 <= 0) {
    const double w = d2 / (d2 - d6);
    r.wb = {1 - w, 0, w};
  } else if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    const double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    r.wb = {0, 1 - w, w};
  } else {
    const double denom = va + vb + vc;
    const double v = vb / denom, w = vc / denom;
    r.wb = {1 - v - w, v, w};
  }
  r.wa = {1, 0, 0};
  // As Finish(r, point, triangle), without building the simplices (same operations, same bits).
  r.pa = p;
  r.pb = r.wb[0] * a;
  r.pb += r.wb[1] * b;
  r.pb += r.wb[2] * c;
  r.dist2 = (r.pa - r.pb).squaredNorm();
  return r;
}

ClosestPair SegmentSegment(const Vec3& p0, const Vec3& p1, const Vec3& q0, const Vec3& q1) {
  // Parallel (relative test): any s works, take the start and fix t, then s.
  const mesh::SegmentParams st = mesh::ClosestSegmentParams(p0, p1, q0, q1, kTinyLength2, 1e-12);
  const double s = st.s, t = st.t;
  ClosestPair r;
  r.wa = {1 - s, s, 0};
  r.wb = {1 - t, t, 0};
  // As Finish(r, segment, segment).
  r.pa = SegmentAt(r.wa[0], r.wa[1], p0, p1);
  r.pb = SegmentAt(r.wb[0], r.wb[1], q0, q1);
  r.dist2 = (r.pa - r.pb).squaredNorm();
  return r;
}

namespace {

// True if segment (p0, p1) crosses the plane of non-degenerate triangle (a, b, c) at a point
// inside it; *r then holds that common point (dist2 = 0).
bool Pierces(const Vec3& p0, const Vec3& p1, const Vec3& a, const Vec3& b, const Vec3& c,
             ClosestPair* r) {
  const Vec3 e0 = b - a, e1 = c - a;
  const Vec3 n = e0.cross(e1);
  const double scale2 = std::max({e0.squaredNorm(), e1.squaredNorm(), (c - b).squaredNorm()});
  if (n.squaredNorm() <= kTinyLength2 * std::max(scale2 * scale2, 1.0)) return false;
  const double s0 = n.dot(p0 - a), s1 = n.dot(p1 - a);
  if (!((s0 <= 0 && s1 >= 0) || (s0 >= 0 && s1 <= 0)) || s0 == s1) return false;
  const double t = s0 / (s0 - s1);
  const Vec3 x = p0 + t * (p1 - p0);
  const Vec3 v2 = x - a;
  const double d00 = e0.dot(e0), d01 = e0.dot(e1), d11 = e1.dot(e1);
  const double d20 = v2.dot(e0), d21 = v2.dot(e1);
  const double den = d00 * d11 - d01 * d01;
  const double v = (d11 * d20 - d01 * d21) / den;
  const double w = (d00 * d21 - d01 * d20) / den;
  if (!(v >= 0 && w >= 0 && v + w <= 1)) return false;
  r->wa = {1 - t, t, 0};
  r->wb = {1 - v - w, v, w};
  r->pa = SegmentSimplex(p0, p1).At(r->wa);
  r->pb = TriangleSimplex(a, b, c).At(r->wb);
  r->dist2 = 0;
  return true;
}

}  // namespace

namespace {

// Cheap lower bounds on distances to a triangle (a, b, c) and to its edges, from its plane and
// its three side planes (through edge k = (v_k, v_k+1), normal to the triangle). They only ever
// skip an exact test whose result could not be taken (it would be farther than the best so
// far), so results are those of the full evaluation, bit for bit. Squared forms: no roots.
struct TriangleFrame {
  Vec3 a, ab, ac, n;  // n = ab x ac, not normalised
  double n2 = 0, d00 = 0, d01 = 0, d11 = 0, inv_denom = 0;
  std::array<double, 3> height2{0, 0, 0};  // squared height over edge k of its opposite vertex
  bool usable = false;                     // well shaped: the bounds are accurate
  double slack = 0;  // rounding allowance of the bounds, mm (far above their error)
};

TriangleFrame MakeFrame(const Vec3& a, const Vec3& b, const Vec3& c) {
  TriangleFrame f;
  f.a = a;
  f.ab = b - a;
  f.ac = c - a;
  f.n = f.ab.cross(f.ac);
  f.n2 = f.n.squaredNorm();
  const double l2[3] = {f.ab.squaredNorm(), (c - b).squaredNorm(), f.ac.squaredNorm()};
  const double max2 = std::max({l2[0], l2[1], l2[2]});
  // Smallest height >= 1e-4 of the longest edge: barycentric coordinates then lose at most ~4
  // digits, ~1e-10 mm at our coordinates, far below `slack`.
  if (!(f.n2 > 1e-8 * max2 * max2)) return f;
  f.d00 = l2[0];
  f.d01 = f.ab.dot(f.ac);
  f.d11 = l2[2];
  f.inv_denom = 1.0 / (f.d00 * f.d11 - f.d01 * f.d01);
  for (int k = 0; k < 3; ++k) f.height2[k] = f.n2 / l2[k];
  f.slack = 1e-9 * (1.0 + a.cwiseAbs().maxCoeff() + std::sqrt(max2));
  f.usable = std::isfinite(f.inv_denom) && std::isfinite(f.slack);
  return f;
}

// Bounds of segment (p0, p1) against a usable frame: plane2 is its squared distance to the
// triangle's plane (0 if it crosses it); side_min/max[k] span the barycentric coordinate of the
// vertex opposite edge k over the segment's projection (affine along it, so the ends bound it):
// times that vertex's height, the signed distance from edge k's side plane (> 0 inside).
struct SegmentBounds {
  double plane2 = 0;
  std::array<double, 3> side_min{0, 0, 0}, side_max{0, 0, 0};
  const TriangleFrame* f = nullptr;

  /// Squared lower bound of the distance from the segment to edge k (mm^2): every point is
  /// that far off the plane and, if side_min > 0, that far inside the edge's side plane.
  double Edge2(int k) const {
    return side_min[k] > 0 ? plane2 + side_min[k] * side_min[k] * f->height2[k] : plane2;
  }
  /// Squared lower bound of the distance from the segment to the triangle (mm^2), which lies in
  /// the plane on the inner side of every side plane.
  double Triangle2() const {
    double out2 = 0;
    for (int k = 0; k < 3; ++k) {
      if (side_max[k] < 0) out2 = std::max(out2, side_max[k] * side_max[k] * f->height2[k]);
    }
    return plane2 + out2;
  }
};

// True if a squared lower bound exceeds dist (mm) by more than the frame's rounding slack.
bool Beyond(const TriangleFrame& f, double lower2, double dist) {
  const double lim = dist + f.slack;
  return lower2 > lim * lim;
}

SegmentBounds BoundSegment(const TriangleFrame& f, const Vec3& p0, const Vec3& p1) {
  SegmentBounds b;
  b.f = &f;
  const Vec3* ends[2] = {&p0, &p1};
  double h[2];
  for (int i = 0; i < 2; ++i) {
    const Vec3 ap = *ends[i] - f.a;
    h[i] = f.n.dot(ap);
    const double d20 = ap.dot(f.ab), d21 = ap.dot(f.ac);
    const double v = (f.d11 * d20 - f.d01 * d21) * f.inv_denom;  // weight of b
    const double w = (f.d00 * d21 - f.d01 * d20) * f.inv_denom;  // weight of c
    // The vertex opposite edge 0 (a, b) is c, opposite edge 1 (b, c) is a, opposite 2 is b.
    const double side[3] = {w, 1.0 - v - w, v};
    for (int k = 0; k < 3; ++k) {
      b.side_min[k] = i == 0 ? side[k] : std::min(b.side_min[k], side[k]);
      b.side_max[k] = i == 0 ? side[k] : std::max(b.side_max[k], side[k]);
    }
  }
  if ((h[0] > 0 && h[1] > 0) || (h[0] < 0 && h[1] < 0)) {
    b.plane2 = std::min(h[0] * h[0], h[1] * h[1]) / f.n2;
  }
  return b;
}

// SegmentTriangle, or false without the exact test when `prune_dist` >= 0 and the triangle is
// provably farther than it from the segment (mm).
bool SegmentTriangleUnless(const Vec3& p0, const Vec3& p1, const Vec3& a, const Vec3& b,
                           const Vec3& c, double prune_dist, ClosestPair* out) {
  const TriangleFrame f = MakeFrame(a, b, c);
  SegmentBounds bounds;
  if (f.usable) {
    bounds = BoundSegment(f, p0, p1);
    if (prune_dist >= 0 && Beyond(f, bounds.Triangle2(), prune_dist)) return false;
  }
  if (Pierces(p0, p1, a, b, c, out)) return true;
  // Otherwise the minimum is at an endpoint against the face or at the segment against an edge.
  const Vec3* tri[3] = {&a, &b, &c};
  ClosestPair best = PointTriangle(p0, a, b, c);
  {
    ClosestPair q = PointTriangle(p1, a, b, c);
    if (q.dist2 < best.dist2) {
      best = q;
      best.wa = {0, 1, 0};
    }
  }
  const int edges[3][2] = {{0, 1}, {1, 2}, {2, 0}};
  for (int k = 0; k < 3; ++k) {
    // An edge no nearer than the best so far cannot replace it (strict improvement).
    if (f.usable && Beyond(f, bounds.Edge2(k), std::sqrt(best.dist2))) continue;
    const auto& e = edges[k];
    const ClosestPair q = SegmentSegment(p0, p1, *tri[e[0]], *tri[e[1]]);
    if (q.dist2 < best.dist2) {
      best = q;
      best.wb = {0, 0, 0};
      best.wb[e[0]] = q.wb[0];
      best.wb[e[1]] += q.wb[1];
    }
  }
  // As Finish(best, segment, triangle), without building the simplices (same bits).
  best.pa = SegmentAt(best.wa[0], best.wa[1], p0, p1);
  best.pb = best.wb[0] * a;
  best.pb += best.wb[1] * b;
  best.pb += best.wb[2] * c;
  best.dist2 = (best.pa - best.pb).squaredNorm();
  *out = best;
  return true;
}

}  // namespace

ClosestPair SegmentTriangle(const Vec3& p0, const Vec3& p1, const Vec3& a, const Vec3& b,
                            const Vec3& c) {
  ClosestPair r;
  SegmentTriangleUnless(p0, p1, a, b, c, -1.0, &r);
  return r;
}

ClosestPair TriangleTriangle(const Simplex& a, const Simplex& b) {
  const int edges[3][2] = {{0, 1}, {1, 2}, {2, 0}};
  // Heights of each triangle's vertices over the other's plane (n not normalised), with the
  // same expressions Pierces uses.
  struct Plane {
    Vec3 n;
    double n2 = 0;
    bool usable = false;  // well shaped: heights / |n| are accurate distances
  };
  auto plane = [](const Simplex& t) {
    Plane p;
    const Vec3 ab = t.v[1] - t.v[0], ac = t.v[2] - t.v[0];
    p.n = ab.cross(ac);
    p.n2 = p.n.squaredNorm();
    p.usable = p.n2 > 1e-8 * ab.squaredNorm() * ac.squaredNorm();
    return p;
  };
  auto heights = [](const Plane& p, const Simplex& tri, const Simplex& other) {
    return std::array<double, 3>{p.n.dot(other.v[0] - tri.v[0]), p.n.dot(other.v[1] - tri.v[0]),
                                 p.n.dot(other.v[2] - tri.v[0])};
  };
  const Plane pa = plane(a), pb = plane(b);
  const std::array<double, 3> ha = heights(pb, b, a), hb = heights(pa, a, b);
  // An edge whose ends are strictly on one side of the other triangle's plane cannot pierce it
  // (Pierces would find the same heights and return false).
  auto apart = [](const std::array<double, 3>& h, const int* e) {
    return (h[e[0]] > 0 && h[e[1]] > 0) || (h[e[0]] < 0 && h[e[1]] < 0);
  };
  // Intersecting (not coplanar): an edge of one crosses the other.
  ClosestPair best;
  for (const auto& e : edges) {
    if (apart(ha, e)) continue;
    if (Pierces(a.v[e[0]], a.v[e[1]], b.v[0], b.v[1], b.v[2], &best)) {
      const std::array<double, 3> w = best.wa;
      best.wa = {0, 0, 0};
      best.wa[e[0]] = w[0];
      best.wa[e[1]] += w[1];
      return best;
    }
  }
  for (const auto& e : edges) {
    if (apart(hb, e)) continue;
    if (Pierces(b.v[e[0]], b.v[e[1]], a.v[0], a.v[1], a.v[2], &best)) {
      best = Swapped(best);
      const std::array<double, 3> w = best.wb;
      best.wb = {0, 0, 0};
      best.wb[e[0]] = w[0];
      best.wb[e[1]] += w[1];
      return best;
    }
  }
  // Otherwise the minimum is a vertex against the other face or an edge against an edge
  // (coplanar overlaps included: a crossing edge pair or a contained vertex gives 0). Fixed
  // evaluation order, strict improvement: ties keep the first candidate. A test is skipped when
  // its plane distance (a lower bound: the other feature lies in that plane) already exceeds
  // the best so far by more than any rounding: it could not be taken.
  const double slack =
      1e-9 * (1.0 + std::max(a.v[0].cwiseAbs().maxCoeff(), b.v[0].cwiseAbs().maxCoeff()) +
              (a.v[0] - b.v[0]).norm());
  // Squared distance bound of points with heights h0, h1 over plane p (0 if it crosses).
  auto lower2 = [](const Plane& p, double h0, double h1) {
    if (!p.usable || !((h0 > 0 && h1 > 0) || (h0 < 0 && h1 < 0))) return 0.0;
    return std::min(h0 * h0, h1 * h1) / p.n2;
  };
  auto cannot_improve = [&](double lb2) {
    if (best.dist2 < 0 || !(lb2 > 0)) return false;
    const double lim = std::sqrt(best.dist2) + slack;
    return lb2 > lim * lim;
  };
  best.dist2 = -1;
  auto take = [&](const ClosestPair& q) {
    if (best.dist2 < 0 || q.dist2 < best.dist2) best = q;
  };
  for (int i = 0; i < 3; ++i) {
    if (cannot_improve(lower2(pb, ha[i], ha[i]))) continue;
    ClosestPair q = PointTriangle(a.v[i], b.v[0], b.v[1], b.v[2]);
    q.wa = {0, 0, 0};
    q.wa[i] = 1;
    take(q);
  }
  for (int i = 0; i < 3; ++i) {
    if (cannot_improve(lower2(pa, hb[i], hb[i]))) continue;
    ClosestPair q = Swapped(PointTriangle(b.v[i], a.v[0], a.v[1], a.v[2]));
    q.wb = {0, 0, 0};
    q.wb[i] = 1;
    take(q);
  }
  for (const auto& ea : edges) {
    for (const auto& eb : edges) {
      // Edge eb lies in b's plane, edge ea in a's.
      if (cannot_improve(
              std::max(lower2(pb, ha[ea[0]], ha[ea[1]]), lower2(pa, hb[eb[0]], hb[eb[1]])))) {
        continue;
      }
      const ClosestPair s = SegmentSegment(a.v[ea[0]], a.v[ea[1]], b.v[eb[0]], b.v[eb[1]]);
      if (!(best.dist2 < 0 || s.dist2 < best.dist2)) continue;
      ClosestPair q = s;
      q.wa = {0, 0, 0};
      q.wa[ea[0]] = s.wa[0];
      q.wa[ea[1]] += s.wa[1];
      q.wb = {0, 0, 0};
      q.wb[eb[0]] = s.wb[0];
      q.wb[eb[1]] += s.wb[1];
      best = q;
    }
  }
  return Finish(best, a, b);
}

ClosestPair Closest(const Simplex& a, const Simplex& b) {
  switch (a.n * 4 + b.n) {
    case 5: {  // point-point
      ClosestPair r;
      r.pa = a.v[0];
      r.pb = b.v[0];
      r.dist2 = (r.pa - r.pb).squaredNorm();
      return r;
    }
    case 6:
      return PointSegment(a.v[0], b.v[0], b.v[1]);
    case 7:
      return PointTriangle(a.v[0], b.v[0], b.v[1], b.v[2]);
    case 9:
      return Swapped(PointSegment(b.v[0], a.v[0], a.v[1]));
    case 10:
      return SegmentSegment(a.v[0], a.v[1], b.v[0], b.v[1]);
    case 11:
      return SegmentTriangle(a.v[0], a.v[1], b.v[0], b.v[1], b.v[2]);
    case 13:
      return Swapped(PointTriangle(b.v[0], a.v[0], a.v[1], a.v[2]));
    case 14:
      return Swapped(SegmentTriangle(b.v[0], b.v[1], a.v[0], a.v[1], a.v[2]));
    default:
      return TriangleTriangle(a, b);
  }
}

bool ClosestUnless(const Simplex& a, const Simplex& b, double prune_dist, ClosestPair* out) {
  if (a.n == 2 && b.n == 3) {
    return SegmentTriangleUnless(a.v[0], a.v[1], b.v[0], b.v[1], b.v[2], prune_dist, out);
  }
  if (a.n == 3 && b.n == 2) {
    if (!SegmentTriangleUnless(b.v[0], b.v[1], a.v[0], a.v[1], a.v[2], prune_dist, out)) {
      return false;
    }
    *out = Swapped(*out);
    return true;
  }

  *out = Closest(a, b);
  return true;
}

double RoundedTriangleGap(const Simplex& core, double radius_mm, const Vec3& a, const Vec3& b,
                          const Vec3& c) {
  return std::sqrt(Closest(core, TriangleSimplex(a, b, c)).dist2) - radius_mm;
}

}  // namespace arthrosim::collision
