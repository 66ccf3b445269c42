#pragma once
// Segment-segment geometry for thread collision: closest points at one instant and a continuous
// (swept) crossing test for two segments whose end points move linearly over a step.
#include "arthrosim/core/types.h"

namespace arthrosim::physics {

/// Closest points p = a0 + s (a1 - a0) and q = b0 + t (b1 - b0), s, t in [0, 1].
struct SegmentClosest {
  double s = 0;
  double t = 0;
  Vec3 p = Vec3::Zero();
  Vec3 q = Vec3::Zero();
  double distance = 0;  ///< |p - q|, mm
};

/// Exact closest points of segments [a0, a1] and [b0, b1] (mm); degenerate segments allowed.
SegmentClosest ClosestPointsSegments(const Vec3& a0, const Vec3& a1, const Vec3& b0,
                                     const Vec3& b1);

/// End points of two segments at the start (x0) and end (x1) of a step; motion is linear in time.
struct SweptSegments {
  Vec3 a0_start, a1_start, b0_start, b1_start;
  Vec3 a0_end, a1_end, b0_end, b1_end;
};

/// Result of a swept test: whether the segments pass through each other during the step.
struct SweptResult {
  bool crosses = false;     ///< segments intersect at some time in [0, 1]
  double time = 1;          ///< first crossing time (fraction of the step), 1 if none
  double min_distance = 0;  ///< smallest distance over the sampled times and roots, mm
  double min_time = 0;      ///< time of that smallest distance
};

/// Continuous test over the linear motion: the four end points become coplanar at the roots of
/// a cubic; the segments cross iff their distance is below tolerance_mm at such a root. Also
/// samples the distance at `samples` + 1 equally spaced times to report the closest approach.
SweptResult SweptSegmentTest(const SweptSegments& m, double tolerance_mm, int samples);

}  // namespace arthrosim::physics
