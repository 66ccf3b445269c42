#pragma once
// Closest points of two segments (Ericson, Real-Time Collision Detection, section 5.1.9), shared
// by collision proximity and the thread solver. Header-only so the bottom layer stays light.
#include <algorithm>

#include "arthrosim/core/types.h"

namespace arthrosim::mesh {

/// Segment parameters: closest points are p0 + s (p1 - p0) and q0 + t (q1 - q0), s, t in [0, 1].
struct SegmentParams {
  double s = 0;
  double t = 0;
};

/// Closest-point parameters of segments [p0, p1] and [q0, q1]. A segment whose squared length is
/// <= tiny_length2 (mm^2) is treated as a point; the segments count as parallel when
/// a e - b^2 <= parallel_tol * a e (then s = 0 and t, s are fixed up by clamping).
inline SegmentParams ClosestSegmentParams(const Vec3& p0, const Vec3& p1, const Vec3& q0,
                                          const Vec3& q1, double tiny_length2,
                                          double parallel_tol) {
  const auto clamp01 = [](double x) { return std::clamp(x, 0.0, 1.0); };
  const Vec3 d1 = p1 - p0, d2 = q1 - q0, r = p0 - q0;
  const double a = d1.dot(d1), e = d2.dot(d2), f = d2.dot(r);
  SegmentParams out;
  if (a <= tiny_length2 && e <= tiny_length2) return out;
  if (a <= tiny_length2) {
    out.t = clamp01(f / e);
    return out;
  }
  const double c = d1.dot(r);
  if (e <= tiny_length2) {
    out.s = clamp01(-c / a);
    return out;
  }
  const double b = d1.dot(d2);
  const double denom = a * e - b * b;  // >= 0; 0 for parallel segments
  double s = denom > parallel_tol * a * e ? clamp01((b * f - c * e) / denom) : 0.0;
  double t = (b * s + f) / e;
  if (t < 0) {
    t = 0;
    s = clamp01(-c / a);
  } else if (t > 1) {
    t = 1;
    s = clamp01((b - c) / a);
  }
  out.s = s;
  out.t = t;
  return out;
}

}  // namespace arthrosim::mesh
