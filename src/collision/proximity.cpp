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

ClosestPair PointSegment(const Vec3& p, const Vec3& a, const Vec3& b) {
  const Vec3 ab = b - a;
  const double len2 = ab.dot(ab);
  const double t = len2 <= kTinyLength2 ? 0.0 : Clamp01((p - a).dot(ab) / len2);
  ClosestPair r;
  r.wa = {1, 0, 0};
  r.wb = {1.0 - t, t, 0};
  return Finish(r, PointSimplex(p), SegmentSimplex(a, b));
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
  return Finish(r, SegmentSimplex(p0, p1), SegmentSimplex(q0, q1));
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

ClosestPair SegmentTriangle(const Vec3& p0, const Vec3& p1, const Vec3& a, const Vec3& b,
                            const Vec3& c) {
  const Simplex seg = SegmentSimplex(p0, p1);
  const Simplex tri = TriangleSimplex(a, b, c);
  {
    ClosestPair r;
    if (Pierces(p0, p1, a, b, c, &r)) return r;
  }
  // Otherwise the minimum is at an endpoint against the face or at the segment against an edge.
  ClosestPair best = PointTriangle(p0, a, b, c);
  {
    ClosestPair q = PointTriangle(p1, a, b, c);
    if (q.dist2 < best.dist2) {
      best = q;
      best.wa = {0, 1, 0};
    }
  }
  const int edges[3][2] = {{0, 1}, {1, 2}, {2, 0}};
  for (const auto& e : edges) {
    const ClosestPair q = SegmentSegment(p0, p1, tri.v[e[0]], tri.v[e[1]]);
    if (q.dist2 < best.dist2) {
      best = q;
      best.wb = {0, 0, 0};
      best.wb[e[0]] = q.wb[0];
      best.wb[e[1]] += q.wb[1];
    }
  }
  return Finish(best, seg, tri);
}

ClosestPair TriangleTriangle(const Simplex& a, const Simplex& b) {
  const int edges[3][2] = {{0, 1}, {1, 2}, {2, 0}};
  // Intersecting (not coplanar): an edge of one crosses the other.
  ClosestPair best;
  for (const auto& e : edges) {
    if (Pierces(a.v[e[0]], a.v[e[1]], b.v[0], b.v[1], b.v[2], &best)) {
      const std::array<double, 3> w = best.wa;
      best.wa = {0, 0, 0};
      best.wa[e[0]] = w[0];
      best.wa[e[1]] += w[1];
      return best;
    }
  }
  for (const auto& e : edges) {
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
  // evaluation order, strict improvement: ties keep the first candidate.
  best.dist2 = -1;
  auto take = [&](const ClosestPair& q) {
    if (best.dist2 < 0 || q.dist2 < best.dist2) best = q;
  };
  for (int i = 0; i < 3; ++i) {
    ClosestPair q = PointTriangle(a.v[i], b.v[0], b.v[1], b.v[2]);
    q.wa = {0, 0, 0};
    q.wa[i] = 1;
    take(q);
  }
  for (int i = 0; i < 3; ++i) {
    ClosestPair q = Swapped(PointTriangle(b.v[i], a.v[0], a.v[1], a.v[2]));
    q.wb = {0, 0, 0};
    q.wb[i] = 1;
    take(q);
  }
  for (const auto& ea : edges) {
    for (const auto& eb : edges) {
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

double RoundedTriangleGap(const Simplex& core, double radius_mm, const Vec3& a, const Vec3& b,
                          const Vec3& c) {
  return std::sqrt(Closest(core, TriangleSimplex(a, b, c)).dist2) - radius_mm;
}

}  // namespace arthrosim::collision
