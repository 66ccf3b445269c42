// Line of sight on analytic scenes: a tip behind a bone sphere or a soft box is hidden, beside
// them seen; a tip just inside a surface is seen within its margin; the surfaces follow the
// frame (a moved bone, dead tets, moved nodes).
#include "arthrosim/scoring/sight.h"

#include <gtest/gtest.h>

#include <numbers>

#include "arthrosim/collision/bench_scene.h"
#include "arthrosim/render/scene.h"
#include "arthrosim/scoring/run_data.h"

namespace arthrosim::scoring {
namespace {

constexpr double kLens = 30.0 * std::numbers::pi / 180.0;

// The scope at the origin looking along +x (its oblique view); a bone sphere of radius 5 at
// x = 20 and a soft box 4 mm thick at x = 20..24 beside it (y = 15..25), both in view.
struct Scene {
  Model model;
  State state;
  Scene() {
    model.soft_bodies.resize(1);
    model.soft_bodies[0].name = "box";
    model.bones.resize(1);
    model.bones[0].name = "sphere";
    const mesh::TetMesh box = collision::BoxTets(Vec3(20, 15, -5), Vec3(24, 25, 5), 2, 4, 4);
    state.soft_bodies.resize(1);
    state.soft_bodies[0].x = box.nodes;
    state.soft_bodies[0].tets = box.tets;
    state.soft_bodies[0].tet_alive.assign(box.tets.size(), 1);
    state.bones.resize(1);
    state.bones[0].surface = collision::Ellipsoid(Vec3(20, 0, 0), Vec3(5, 5, 5), 48, 25);
    state.bones[0].revision = 1;
    state.camera.pose = render::AimScope(Vec3::Zero(), Vec3(1, 0, 0), Vec3::UnitZ(), kLens);
  }
  bool Seen(const Vec3& tip, double margin_mm = 1.0) {
    SightBlockers blockers;
    blockers.Update(model, state);
    return TipVisible(model, state.camera, tip, margin_mm, blockers);
  }
};

TEST(Sight, ATipBehindABoneSphereIsHiddenAndBesideItSeen) {
  Scene s;
  ASSERT_TRUE(PointInView(s.model, s.state.camera, Vec3(35, 0, 0)));
  EXPECT_FALSE(s.Seen(Vec3(35, 0, 0)));  // behind the sphere's centre
  EXPECT_FALSE(s.Seen(Vec3(35, 3, 2)));  // behind it off centre (the line passes at 2.0 mm)
  EXPECT_TRUE(s.Seen(Vec3(35, 10, 0)));  // beside it (the line passes 5.5 mm from the centre)
  EXPECT_TRUE(s.Seen(Vec3(12, 0, 0)));   // in front of it
  EXPECT_FALSE(s.Seen(Vec3(20, 0, 0)));  // at the centre: 5 mm inside, beyond a 1 mm margin
}

TEST(Sight, ATipJustInsideASurfaceIsSeenWithinItsMargin) {
  Scene s;
  // 0.5 mm into the sphere's near side (x = 15): the crossing lies 0.5 mm before the tip
  EXPECT_TRUE(s.Seen(Vec3(15.5, 0, 0), 1.0));
  EXPECT_FALSE(s.Seen(Vec3(15.5, 0, 0), 0.2));
}

TEST(Sight, ATipBehindASoftBoxIsHiddenUntilItsTetsAreGone) {
  Scene s;
  const Vec3 tip(40, 40, 0);  // behind the box: the line crosses it at y = 20..24
  ASSERT_TRUE(PointInView(s.model, s.state.camera, tip));
  EXPECT_FALSE(s.Seen(tip));
  EXPECT_TRUE(s.Seen(Vec3(40, 40, 20)));  // over the box (the line at z 10..12 there)
  std::fill(s.state.soft_bodies[0].tet_alive.begin(), s.state.soft_bodies[0].tet_alive.end(), 0);
  EXPECT_TRUE(s.Seen(tip));  // cut away
}

TEST(Sight, TheSurfacesFollowTheFrame) {
  Scene s;
  SightBlockers blockers;
  const Vec3 behind_sphere(35, 0, 0), behind_box(40, 40, 0);
  blockers.Update(s.model, s.state);
  EXPECT_FALSE(TipVisible(s.model, s.state.camera, behind_sphere, 1.0, blockers));
  // the bone burred away (a new surface: a small sphere far off) and the box moved up 30 mm
  s.state.bones[0].surface = collision::Ellipsoid(Vec3(20, -30, 0), Vec3(1, 1, 1), 8, 5);
  s.state.bones[0].revision = 2;
  for (Eigen::Index n = 0; n < s.state.soft_bodies[0].x.cols(); ++n)
    s.state.soft_bodies[0].x(2, n) += 30;
  blockers.Update(s.model, s.state);
  EXPECT_TRUE(TipVisible(s.model, s.state.camera, behind_sphere, 1.0, blockers));
  EXPECT_TRUE(TipVisible(s.model, s.state.camera, behind_box, 1.0, blockers));
  // and back: the moved nodes hide it again
  for (Eigen::Index n = 0; n < s.state.soft_bodies[0].x.cols(); ++n)
    s.state.soft_bodies[0].x(2, n) -= 30;
  blockers.Update(s.model, s.state);
  EXPECT_FALSE(TipVisible(s.model, s.state.camera, behind_box, 1.0, blockers));
}

TEST(Sight, OutOfTheViewConeIsNotSeenAndCountsMustMatch) {
  Scene s;
  EXPECT_FALSE(s.Seen(Vec3(-10, 0, 0)));  // behind the scope
  State bad = s.state;
  bad.bones.clear();
  SightBlockers blockers;
  EXPECT_THROW(blockers.Update(s.model, bad), std::invalid_argument);
}

}  // namespace
}  // namespace arthrosim::scoring
