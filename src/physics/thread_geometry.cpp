#include "arthrosim/physics/thread_geometry.h"

#include "arthrosim/mesh/segment_closest.h"

#include <algorithm>
#include <array>
#include <cmath>

namespace arthrosim::physics {

namespace {

// Cubic c0 + c1 t + c2 t^2 + c3 t^3.
double EvalCubic(const std::array<double, 4>& c, double t) {
  return c[0] + t * (c[1] + t * (c[2] + t * c[3]));
}

// Roots of the cubic in [0, 1], ascending. The interval is split at the real roots of the
// derivative so each piece is monotone, then every sign change is bisected to ~1e-14.
int CubicRootsIn01(const std::array<double, 4>& c, std::array<double, 3>* roots) {
  std::array<double, 4> knots{0, 1, 1, 1};
  int nk = 1;
  const double a = 3 * c[3], b = 2 * c[2], cc = c[1];
  if (std::abs(a) > 0) {
    const double disc = b * b - 4 * a * cc;
    if (disc >= 0) {
      const double sq = std::sqrt(disc);
      double r1 = (-b - sq) / (2 * a), r2 = (-b + sq) / (2 * a);
      if (r1 > r2) std::swap(r1, r2);
      if (r1 > 0 && r1 < 1) knots[nk++] = r1;
      if (r2 > 0 && r2 < 1 && r2 != r1) knots[nk++] = r2;
    }
  } else if (std::abs(b) > 0) {
    const double r = -cc / b;
    if (r > 0 && r < 1) knots[nk++] = r;
  }
  knots[nk++] = 1;
  int n = 0;
  for (int k = 0; k + 1 < nk; ++k) {
    double lo = knots[k], hi = knots[k + 1];
    double flo = EvalCubic(c, lo), fhi = EvalCubic(c, hi);
    if (flo == 0) {
      if (n == 0 || (*roots)[n - 1] != lo) (*roots)[n++] = lo;
      continue;
    }
    if (fhi == 0) {
      if (k + 2 == nk) (*roots)[n++] = hi;  // interior knots are caught as the next lo
      continue;
    }
    if ((flo < 0) == (fhi < 0)) continue;
    for (int it = 0; it < 60 && hi - lo > 1e-14; ++it) {
      const double mid = 0.5 * (lo + hi);
      const double fm = EvalCubic(c, mid);
      if ((fm < 0) == (flo < 0)) {
        lo = mid;
        flo = fm;
      } else {
        hi = mid;
      }
    }
    if (n < 3) (*roots)[n++] = 0.5 * (lo + hi);
  }
  return n;
}

Vec3 Lerp(const Vec3& a, const Vec3& b, double t) { return a + t * (b - a); }

double DistanceAt(const SweptSegments& m, double t) {
  return ClosestPointsSegments(Lerp(m.a0_start, m.a0_end, t), Lerp(m.a1_start, m.a1_end, t),
                               Lerp(m.b0_start, m.b0_end, t), Lerp(m.b1_start, m.b1_end, t))
      .distance;
}

}  // namespace

SegmentClosest ClosestPointsSegments(const Vec3& a0, const Vec3& a1, const Vec3& b0,
                                     const Vec3& b1) {
  const mesh::SegmentParams st = mesh::ClosestSegmentParams(a0, a1, b0, b1, 1e-30, 1e-14);
  const double s = st.s, t = st.t;
  const Vec3 d1 = a1 - a0, d2 = b1 - b0;
  SegmentClosest out;
  out.s = s;
  out.t = t;
  out.p = a0 + s * d1;
  out.q = b0 + t * d2;
  out.distance = (out.p - out.q).norm();
  return out;
}

SweptResult SweptSegmentTest(const SweptSegments& m, double tolerance_mm, int samples) {
  SweptResult res;
  res.min_distance = DistanceAt(m, 0);
  res.min_time = 0;
  const int n = std::max(1, samples);
  for (int k = 1; k <= n; ++k) {
    const double t = static_cast<double>(k) / n;
    const double d = DistanceAt(m, t);
    if (d < res.min_distance) {
      res.min_distance = d;
      res.min_time = t;
    }
  }
  // Coplanarity det[a1 - a0, b0 - a0, b1 - a0](t), each column linear in t.
  const Vec3 u0 = m.a1_start - m.a0_start, u1 = (m.a1_end - m.a0_end) - u0;
  const Vec3 v0 = m.b0_start - m.a0_start, v1 = (m.b0_end - m.a0_end) - v0;
  const Vec3 w0 = m.b1_start - m.a0_start, w1 = (m.b1_end - m.a0_end) - w0;
  const Vec3 vw0 = v0.cross(w0), vw1 = v0.cross(w1) + v1.cross(w0), vw2 = v1.cross(w1);
  const std::array<double, 4> c{u0.dot(vw0), u1.dot(vw0) + u0.dot(vw1), u0.dot(vw2) + u1.dot(vw1),
                                u1.dot(vw2)};
  const double scale =
      std::max({u0.norm() + u1.norm(), v0.norm() + v1.norm(), w0.norm() + w1.norm(), 1e-12});
  const double cmax = std::max({std::abs(c[0]), std::abs(c[1]), std::abs(c[2]), std::abs(c[3])});
  if (cmax <= 1e-13 * scale * scale * scale) {
    // Coplanar during the whole step: the sampled distances decide.
    if (res.min_distance <= tolerance_mm) {
      res.crosses = true;
      res.time = res.min_time;
    }
    return res;
  }
  std::array<double, 3> roots{};
  const int nr = CubicRootsIn01(c, &roots);
  for (int k = 0; k < nr; ++k) {
    const double d = DistanceAt(m, roots[k]);
    if (d < res.min_distance) {
      res.min_distance = d;
      res.min_time = roots[k];
    }
    if (d <= tolerance_mm && !res.crosses) {
      res.crosses = true;
      res.time = roots[k];
    }
  }
  return res;
}

}  // namespace arthrosim::physics
