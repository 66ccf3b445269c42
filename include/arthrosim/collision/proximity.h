#pragma once
// Exact closest points between simplices (point, segment, triangle). Every narrow-phase test of
// the collision stage goes through these functions, so they are written once, branch only on
// geometry (never on memory order) and are tested against brute-force sampling. Units: mm.
//
// A "rounded simplex" (core simplex + radius) models spheres (point core), capsules (segment
// core), thin blades and jaws (triangle core) and thread segments (segment core).
#include <array>

#include "arthrosim/core/types.h"

namespace arthrosim::collision {

/// A point (n = 1), segment (n = 2) or triangle (n = 3); unused vertices are zero.
struct Simplex {
  int n = 1;
  std::array<Vec3, 3> v{Vec3::Zero(), Vec3::Zero(), Vec3::Zero()};

  /// The point with barycentric weights w (sum 1) on this simplex, mm.
  Vec3 At(const std::array<double, 3>& w) const;
};

/// Simplex constructors.
Simplex PointSimplex(const Vec3& a);
Simplex SegmentSimplex(const Vec3& a, const Vec3& b);
Simplex TriangleSimplex(const Vec3& a, const Vec3& b, const Vec3& c);

/// Closest pair between two simplices: weights wa on A and wb on B (each >= 0, sum 1; weights of
/// unused vertices are 0), the points pa = A.At(wa), pb = B.At(wb), and |pa - pb|^2 (mm^2).
/// Intersecting simplices give dist2 = 0 and a common point.
struct ClosestPair {
  std::array<double, 3> wa{1, 0, 0};
  std::array<double, 3> wb{1, 0, 0};
  Vec3 pa = Vec3::Zero();
  Vec3 pb = Vec3::Zero();
  double dist2 = 0;
};

/// Closest point on triangle (a, b, c) to p. Degenerate triangles are handled through their edges.
ClosestPair PointTriangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c);
/// Closest point on segment (a, b) to p; a zero-length segment is its point a.
ClosestPair PointSegment(const Vec3& p, const Vec3& a, const Vec3& b);
/// Closest points between segments (p0, p1) and (q0, q1), degenerate and parallel cases included.
ClosestPair SegmentSegment(const Vec3& p0, const Vec3& p1, const Vec3& q0, const Vec3& q1);
/// Closest points between segment (p0, p1) and triangle (a, b, c); 0 when the segment pierces it.
ClosestPair SegmentTriangle(const Vec3& p0, const Vec3& p1, const Vec3& a, const Vec3& b,
                            const Vec3& c);
/// Closest points between triangles A and B; 0 when they intersect.
ClosestPair TriangleTriangle(const Simplex& a, const Simplex& b);
/// Closest points between any two simplices (dispatches to the functions above).
ClosestPair Closest(const Simplex& a, const Simplex& b);

/// Closest(a, b) into *out, or false (*out unspecified) when a cheap bound proves the two farther
/// apart than prune_dist (mm; < 0 = never). Skipping only what cannot be nearer, so a search for
/// the nearest of many simplices finds the same pair, bit for bit, as with Closest.
bool ClosestUnless(const Simplex& a, const Simplex& b, double prune_dist, ClosestPair* out);

/// Signed gap between a rounded simplex (core, radius) and a triangle: core distance - radius,
/// mm (< 0 = overlap). Sphere-triangle and capsule-triangle are the n = 1 and n = 2 cases.
double RoundedTriangleGap(const Simplex& core, double radius_mm, const Vec3& a, const Vec3& b,
                          const Vec3& c);

}  // namespace arthrosim::collision
