#include "arthrosim/scoring/motion.h"

#include <limits>
#include <stdexcept>

namespace arthrosim::scoring {
namespace {

void CheckSegment(const Segment& s) {
  if (s.t_s.size() != s.p_mm.size())
    throw std::invalid_argument("motion segment: times and positions differ in length");
  for (std::size_t i = 1; i < s.t_s.size(); ++i)
    if (!(s.t_s[i] > s.t_s[i - 1]))
      throw std::invalid_argument("motion segment: times must increase");
}

}  // namespace

double PathLength(const Track& track) {
  double length = 0;
  for (const Segment& s : track)
    for (std::size_t i = 1; i < s.p_mm.size(); ++i) length += (s.p_mm[i] - s.p_mm[i - 1]).norm();
  return length;
}

double SquaredJerkIntegral(const Track& track) {
  double integral = 0;
  for (const Segment& s : track) {
    for (std::size_t i = 0; i + 3 < s.p_mm.size(); ++i) {
      const double h = (s.t_s[i + 3] - s.t_s[i]) / 3.0;
      const Vec3 d3 = s.p_mm[i + 3] - 3.0 * s.p_mm[i + 2] + 3.0 * s.p_mm[i + 1] - s.p_mm[i];
      const Vec3 jerk = d3 / (h * h * h);
      integral += jerk.squaredNorm() * h;
    }
  }
  return integral;
}

MotionMetrics ComputeMotion(const Track& track, double movement_speed_mm_s,
                            double idle_speed_mm_s) {
  MotionMetrics m;
  bool any_jerk_window = false;
  for (const Segment& s : track) {
    CheckSegment(s);
    if (s.t_s.size() >= 2) m.time_s += s.t_s.back() - s.t_s.front();
    if (s.t_s.size() >= 4) any_jerk_window = true;
    bool previous_moving = false;
    for (std::size_t i = 0; i + 1 < s.p_mm.size(); ++i) {
      const double dt = s.t_s[i + 1] - s.t_s[i];
      const double speed = (s.p_mm[i + 1] - s.p_mm[i]).norm() / dt;
      const bool moving = speed > movement_speed_mm_s;
      if (moving && !previous_moving) ++m.movements;
      previous_moving = moving;
      if (speed < idle_speed_mm_s) m.idle_time_s += dt;
    }
  }
  m.path_length_mm = PathLength(track);
  if (m.path_length_mm > 0 && any_jerk_window) {
    const double t = m.time_s;
    m.dimensionless_jerk =
        t * t * t * t * t * SquaredJerkIntegral(track) / (m.path_length_mm * m.path_length_mm);
  } else {
    m.dimensionless_jerk = std::numeric_limits<double>::quiet_NaN();
  }
  return m;
}

}  // namespace arthrosim::scoring
