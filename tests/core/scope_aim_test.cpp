// AimScopeView on analytic cases: the oblique view (not the shaft) hits the target, the image up
// follows the hint, the vertical and degenerate fallbacks, lens angle 0 aims the shaft.
#include "arthrosim/core/scope_aim.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>

namespace arthrosim {
namespace {

constexpr double kPi = std::numbers::pi;

TEST(ScopeAim, ViewDirectionLocalTiltsTowardPlusY) {
  EXPECT_NEAR((ScopeViewDirectionLocal(0) - Vec3::UnitZ()).norm(), 0, 1e-15);
  EXPECT_NEAR((ScopeViewDirectionLocal(kPi / 6) - Vec3(0, 0.5, std::sqrt(3) / 2)).norm(), 0, 1e-15);
}

TEST(ScopeAim, TheObliqueViewLooksAtTheTargetWithTheImageUpTowardTheHint) {
  const Vec3 eyes[] = {Vec3(-30, 0, 8), Vec3(10, -25, 3), Vec3(2, 3, -1)};
  const Vec3 targets[] = {Vec3(0, 0, 5), Vec3(4, 7, -12), Vec3(-3, 20, 1)};
  for (const double lens_deg : {0.0, 30.0, 70.0}) {
    const double a = lens_deg * kPi / 180;
    for (const Vec3& eye : eyes) {
      for (const Vec3& target : targets) {
        const Quat q = AimScopeView(eye, target, a);
        EXPECT_NEAR(q.norm(), 1.0, 1e-12);
        const Vec3 f = (target - eye).normalized();
        const Vec3 view = q * ScopeViewDirectionLocal(a);
        EXPECT_NEAR((view - f).norm(), 0, 1e-12) << lens_deg;
        // the shaft is lens_deg off the view
        EXPECT_NEAR(std::acos(std::clamp((q * Vec3::UnitZ()).dot(f), -1.0, 1.0)), a, 1e-7);
        // image up (+y tilted back by the lens angle) lies in the plane of the view and world
        // +z, on the +z side: the horizon is level
        const Vec3 up = q * Vec3(0, std::cos(a), -std::sin(a));
        EXPECT_NEAR(up.dot(f.cross(Vec3::UnitZ()).normalized()), 0, 1e-12);
        EXPECT_GT(up.dot(Vec3::UnitZ()), 0);
      }
    }
  }
}

TEST(ScopeAim, LensAngleZeroAimsTheShaftAndAnUpHintIsHonoured) {
  const Quat q = AimScopeView(Vec3(-30, 0, 8), Vec3(0, 0, 8), 0.0);
  EXPECT_NEAR((q * Vec3::UnitZ() - Vec3::UnitX()).norm(), 0, 1e-15);
  EXPECT_NEAR((q * Vec3::UnitY() - Vec3::UnitZ()).norm(), 0, 1e-15);
  const Quat h = AimScopeView(Vec3::Zero(), Vec3(0, 0, 10), 0.0, Vec3::UnitY());
  EXPECT_NEAR((h * Vec3::UnitY() - Vec3::UnitY()).norm(), 0, 1e-15);
}

TEST(ScopeAim, VerticalViewFallsBackToWorldYAndEyeOnTargetIsIdentity) {
  const double a = kPi / 6;
  for (const double dz : {-10.0, 10.0}) {
    const Quat q = AimScopeView(Vec3::Zero(), Vec3(0, 0, dz), a);
    const Vec3 view = q * ScopeViewDirectionLocal(a);
    EXPECT_NEAR((view - Vec3(0, 0, dz > 0 ? 1 : -1)).norm(), 0, 1e-12);
    EXPECT_NEAR((q * Vec3(0, std::cos(a), -std::sin(a)) - Vec3::UnitY()).norm(), 0, 1e-12);
  }
  // a hint along world y viewed along y: any perpendicular, still a unit rotation on the target
  const Quat q = AimScopeView(Vec3::Zero(), Vec3(0, 5, 0), a, Vec3::UnitY());
  EXPECT_NEAR((q * ScopeViewDirectionLocal(a) - Vec3::UnitY()).norm(), 0, 1e-12);
  EXPECT_TRUE(AimScopeView(Vec3(1, 2, 3), Vec3(1, 2, 3), a).coeffs() == Quat::Identity().coeffs());
}

}  // namespace
}  // namespace arthrosim
