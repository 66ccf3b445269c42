// Motion metrics on analytic trajectories whose values are known in closed form.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "arthrosim/scoring/motion.h"

namespace arthrosim::scoring {
namespace {

constexpr double kPi = std::numbers::pi;

// n + 1 samples of f on [0, T].
template <class F>
Track Sample(double duration_s, int n, F f) {
  Segment s;
  for (int i = 0; i <= n; ++i) {
    const double t = duration_s * i / n;
    s.t_s.push_back(t);
    s.p_mm.push_back(f(t));
  }
  return {s};
}

TEST(Motion, StraightLineAtConstantSpeed) {
  // 20 mm/s along (3, 4, 0)/5 for 2 s: 40 mm, one movement, never idle, no jerk.
  const Vec3 dir = Vec3(3, 4, 0) / 5.0;
  const Track track =
      Sample(2.0, 200, [&](double t) -> Vec3 { return Vec3(1, 2, 3) + 20.0 * t * dir; });
  const MotionMetrics m = ComputeMotion(track, 7.5, 5.0);
  EXPECT_NEAR(m.path_length_mm, 40.0, 1e-9);
  EXPECT_NEAR(m.time_s, 2.0, 1e-12);
  EXPECT_EQ(m.movements, 1);
  EXPECT_EQ(m.idle_time_s, 0.0);
  EXPECT_LT(std::abs(m.dimensionless_jerk), 1e-6);
  // Slower than the movement threshold: no movement, and idle below 5 mm/s.
  const Track slow = Sample(2.0, 200, [&](double t) -> Vec3 { return 4.0 * t * dir; });
  const MotionMetrics s = ComputeMotion(slow, 7.5, 5.0);
  EXPECT_EQ(s.movements, 0);
  EXPECT_NEAR(s.idle_time_s, 2.0, 1e-12);
}

TEST(Motion, MinimumJerkReachHasDimensionlessJerk720) {
  // x(t) = D (10 s^3 - 15 s^4 + 6 s^5), s = t / T: integral of jerk^2 = 720 D^2 / T^5, so
  // (T^5 / D^2) * integral = 720 for any D and T.
  for (const double d : {5.0, 40.0}) {
    for (const double duration : {0.5, 2.0}) {
      const Track track = Sample(duration, 20000, [&](double t) -> Vec3 {
        const double s = t / duration;
        return Vec3(0, d * s * s * s * (10 - 15 * s + 6 * s * s), 0);
      });
      const MotionMetrics m = ComputeMotion(track, 7.5, 5.0);
      EXPECT_NEAR(m.path_length_mm, d, 1e-9 * d);
      EXPECT_NEAR(m.dimensionless_jerk, 720.0, 720.0 * 2e-3) << "D " << d << " T " << duration;
      // Peak speed 1.875 D / T: one movement when it exceeds 7.5 mm/s, none otherwise.
      EXPECT_EQ(m.movements, 1.875 * d / duration > 7.5 ? 1 : 0);
    }
  }
}

TEST(Motion, SinusoidPathMovementsIdleAndJerk) {
  // x = A sin(w t) over one period T = 2 pi / w: path 4A; speed A w |cos w t| drops to 0 at
  // T/4 and 3T/4, so 3 movements; idle while A w |cos| < v0: 4 asin(v0 / (A w)) / w;
  // jerk^2 integral = A^2 w^6 T / 2, so DSJ = T^5 (A^2 w^6 T / 2) / (4A)^2 = (2 pi)^6 / 32.
  const double a = 10.0, w = 2.0 * kPi, period = 1.0;
  const int n = 20000;
  const Track track =
      Sample(period, n, [&](double t) -> Vec3 { return Vec3(a * std::sin(w * t), 0, 0); });
  const MotionMetrics m = ComputeMotion(track, 7.5, 5.0);
  EXPECT_NEAR(m.path_length_mm, 4 * a, 1e-6);
  EXPECT_EQ(m.movements, 3);
  const double idle = 4.0 * std::asin(5.0 / (a * w)) / w;
  EXPECT_NEAR(m.idle_time_s, idle, 2.0 * period / n);
  EXPECT_NEAR(m.dimensionless_jerk, std::pow(2 * kPi, 6) / 32.0, 1e-3 * std::pow(2 * kPi, 6) / 32);
}

TEST(Motion, SegmentsDoNotBridgeRemovals) {
  // Two insertions 100 mm apart: the jump between them is not path, each opens a movement.
  Track track = Sample(1.0, 100, [](double t) -> Vec3 { return Vec3(10.0 * t, 0, 0); });
  Track second = Sample(1.0, 100, [](double t) -> Vec3 { return Vec3(100.0 + 10.0 * t, 0, 0); });
  for (double& t : second[0].t_s) t += 5.0;
  track.push_back(second[0]);
  const MotionMetrics m = ComputeMotion(track, 7.5, 5.0);
  EXPECT_NEAR(m.path_length_mm, 20.0, 1e-9);
  EXPECT_NEAR(m.time_s, 2.0, 1e-12);
  EXPECT_EQ(m.movements, 2);
}

TEST(Motion, RejectsNonIncreasingTimes) {
  Segment s;
  s.t_s = {0.0, 0.0};
  s.p_mm = {Vec3::Zero(), Vec3::Ones()};
  EXPECT_THROW(ComputeMotion({s}, 7.5, 5.0), std::invalid_argument);
}

TEST(Motion, NoMotionHasUndefinedJerk) {
  const Track still = Sample(1.0, 10, [](double) -> Vec3 { return Vec3(1, 1, 1); });
  EXPECT_TRUE(std::isnan(ComputeMotion(still, 7.5, 5.0).dimensionless_jerk));
}

}  // namespace
}  // namespace arthrosim::scoring
