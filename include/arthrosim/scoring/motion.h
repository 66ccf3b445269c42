#pragma once
// Motion metrics of a sampled tip trajectory (docs/metrics.md gives each formula). A Track is a
// list of segments: the times an instrument was inserted, each sampled at the run's frames.
// Nothing is filtered or resampled: every metric is a fixed function of the samples.
#include <vector>

#include "arthrosim/core/types.h"

namespace arthrosim::scoring {

/// Contiguous samples of one insertion: times (s, increasing) and tip positions (mm).
struct Segment {
  std::vector<double> t_s;
  std::vector<Vec3> p_mm;
};
using Track = std::vector<Segment>;

struct MotionMetrics {
  double path_length_mm = 0;  ///< sum of |p[i+1] - p[i]| within segments
  double time_s = 0;          ///< sum of segment durations (last minus first time)
  int movements = 0;          ///< rises of the interval speed above the movement threshold
  double idle_time_s = 0;     ///< sum of interval durations with speed below the idle threshold
  /// Dimensionless squared jerk: (T^5 / L^2) * integral |d3p/dt3|^2 dt, T = time_s,
  /// L = path_length_mm, jerk from third differences. NaN when L = 0 or no segment has 4 samples.
  double dimensionless_jerk = 0;
};

/// Computes every motion metric of `track`.
/// `movement_speed_mm_s`: a movement starts at an interval whose speed exceeds it while the
/// previous interval's did not (or that opens a segment); `idle_speed_mm_s`: intervals slower
/// than it count as idle. @throws std::invalid_argument if times do not increase or a segment's
/// times and positions differ in length.
MotionMetrics ComputeMotion(const Track& track, double movement_speed_mm_s, double idle_speed_mm_s);

/// Sum of |p[i+1] - p[i]| over the samples of every segment, mm.
double PathLength(const Track& track);

/// Integral of |jerk|^2 dt (mm^2/s^5) from third differences p[i+3] - 3p[i+2] + 3p[i+1] - p[i]
/// over h^3 (h = mean step of the window), each weighted by h; segments under 4 samples add 0.
double SquaredJerkIntegral(const Track& track);

}  // namespace arthrosim::scoring
