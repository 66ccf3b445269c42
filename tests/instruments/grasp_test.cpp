// Grasper and retriever on the slab scene, through the whole step (collision, solvers,
// instrument stage): the grasped point follows the tool, the spring goes when the jaw opens or
// the limit is exceeded, the retriever lifts a thread node by the commanded distance.
#include <gtest/gtest.h>

#include "arthrosim/core/parallel.h"
#include "arthrosim/physics/constraints.h"
#include "suture_scene.h"

namespace arthrosim::instruments {
namespace {

using testing::SlotDriver;

std::int64_t GraspId(const State& s) {
  const std::vector<std::int64_t> ids = physics::FindConstraintsByTag(s, "grasp");
  return ids.empty() ? -1 : ids.front();
}

// Presses the closed grasper onto the slab's top face near its free end: grasps at step 4.
void TakeHold(SlotDriver* d, const Vec3& at) {
  for (int k = 0; k < 3; ++k) d->Step(at, 0.0);
  EXPECT_EQ(GraspId(*d->state), -1) << "no grasp while the jaw is open";
  d->Step(at, 1.0);
  ASSERT_EQ(d->Events("grasp").size(), 1u);
  EXPECT_EQ(d->Events("grasp")[0].body, "tendon");
  ASSERT_GE(GraspId(*d->state), 0);
}

// The grasper holding the slab's top face near its free end (TakeHold at `start`).
class GrasperHolding : public ::testing::Test {
 protected:
  void SetUp() override {
    TakeHold(&d, start);
    id = GraspId(s);
  }
  const Model m = testing::SlabModel();
  State s = MakeInitialState(m);
  SlotDriver d{m, &s, "grasper"};
  const Vec3 start{25, 10, 4.4};
  std::int64_t id = -1;  ///< the grasp spring
};

TEST_F(GrasperHolding, GraspedPointFollowsTheToolAndLetsGoWhenTheJawOpens) {
  const Vec3 grasped0 = physics::EndPosition(s, physics::FindConstraint(s, id)->b);
  double worst_mm = 0;
  for (int k = 1; k <= 30; ++k) {  // lift 3 mm at 5 mm/s
    d.Step(start + Vec3(0, 0, 0.1 * k), 1.0);
    const SpringConstraint* c = physics::FindConstraint(s, id);
    ASSERT_NE(c, nullptr) << "released at lift step " << k;
    worst_mm =
        std::max(worst_mm, (physics::EndPosition(s, c->a) - physics::EndPosition(s, c->b)).norm());
  }
  EXPECT_LT(worst_mm, 1.0);
  const Vec3 grasped = physics::EndPosition(s, physics::FindConstraint(s, id)->b);
  EXPECT_GT(grasped.z() - grasped0.z(), 2.5) << "the tissue point was lifted with the tool";
  // Open the jaw: released in that step, so the next step has no spring.
  d.Step(start + Vec3(0, 0, 3.0), 0.0);
  ASSERT_EQ(d.Events("release").size(), 1u);
  EXPECT_NE(d.Events("release")[0].detail.find("reason=jaw_open"), std::string::npos);
  EXPECT_EQ(physics::FindConstraint(s, id), nullptr);
  EXPECT_TRUE(s.soft_bodies[0].x.allFinite());
}

TEST_F(GrasperHolding, WithdrawingTheInstrumentReleasesItsHold) {
  d.frame.tools[0].instrument = -1;  // withdrawn through its portal with the jaw still closed
  d.Step(start + Vec3(0, 0, 20), 1.0);
  EXPECT_EQ(physics::FindConstraint(s, id), nullptr) << "the tissue stays tied to an empty slot";
  EXPECT_TRUE(physics::FindConstraintsByEnd(s, ConstraintEnd::Kind::kTool, 0).empty());
  ASSERT_EQ(d.Events("release").size(), 1u);
  EXPECT_EQ(d.Events("release")[0].body, "tendon");
  EXPECT_NE(d.Events("release")[0].detail.find("tag=grasp reason=withdrawn"), std::string::npos)
      << d.Events("release")[0].detail;
  EXPECT_TRUE(s.soft_bodies[0].x.allFinite());
}

TEST_F(GrasperHolding, ReleasesWhenTheStretchExceedsDistLimit) {
  // An 8 mm jerk along the slab in one step: its axial stiffness (about 16 N/mm) exceeds the
  // grasp spring's (5 N/mm), so the point cannot follow within Dist_Limit (2 mm).
  d.Step(start + Vec3(8, 0, 1), 1.0);
  ASSERT_EQ(d.Events("release").size(), 1u);
  const std::string detail = d.Events("release")[0].detail;
  EXPECT_NE(detail.find("reason=distance"), std::string::npos) << detail;
  EXPECT_EQ(physics::FindConstraint(s, id), nullptr);
  // The jaw is still closed but the tool is away from the tissue: no new grasp.
  d.Step(start + Vec3(8, 0, 3), 1.0);
  EXPECT_EQ(GraspId(s), -1);
}

TEST(Grasper, DistLimitIsAScenarioKey) {
  // With a 10 mm limit the same jerk keeps the grasp.
  const Model m = testing::SlabModel("operations: {grasper: {dist_limit: 10}}\n");
  EXPECT_EQ(m.operations.grasper.dist_limit_mm, 10.0);
  State s = MakeInitialState(m);
  SlotDriver d(m, &s, "grasper");
  const Vec3 start(25, 10, 4.4);
  TakeHold(&d, start);
  d.Step(start + Vec3(8, 0, 1), 1.0);
  EXPECT_TRUE(d.Events("release").empty());
  EXPECT_GE(GraspId(s), 0);
}

TEST(Retriever, LiftsAThreadNodeByTheCommandedDistance) {
  const Model m = testing::SlabModel();
  State s = MakeInitialState(m);
  SlotDriver d(m, &s, "retriever");
  const Vec3 start(26, 10, 8.9);  // jaw tip 0.9 mm above thread node 20
  for (int k = 0; k < 2; ++k) d.Step(start, 0.0);
  d.Step(start, 1.0);
  ASSERT_EQ(d.Events("grasp").size(), 1u);
  EXPECT_EQ(d.Events("grasp")[0].body, "suture");
  EXPECT_NE(d.Events("grasp")[0].detail.find("node=20"), std::string::npos)
      << d.Events("grasp")[0].detail;
  const double z0 = s.threads[0].x(2, 20);
  for (int k = 1; k <= 25; ++k) d.Step(start + Vec3(0, 0, 0.2 * k), 1.0);  // up 5 mm
  for (int k = 0; k < 10; ++k) d.Step(start + Vec3(0, 0, 5), 1.0);         // hold
  EXPECT_NEAR(s.threads[0].x(2, 20) - z0, 5.0, 0.3);
  EXPECT_GE(GraspId(s), 0);
  EXPECT_TRUE(s.threads[0].x.allFinite());
  d.Step(start + Vec3(0, 0, 5), 0.0);
  EXPECT_EQ(d.Events("release").size(), 1u);
  EXPECT_EQ(GraspId(s), -1);
}

State GraspRun(const Model& m) {
  State s = MakeInitialState(m);
  SlotDriver d(m, &s, "grasper");
  const Vec3 start(25, 10, 4.4);
  for (int k = 0; k < 3; ++k) d.Step(start, 0.0);
  for (int k = 0; k < 20; ++k) d.Step(start + Vec3(0, 0.1 * k, 0.1 * k), 1.0);
  d.Step(start + Vec3(0, 2, 2), 0.0);
  return s;
}

TEST(Grasper, BitIdenticalForOneAndTwoThreads) {
  const auto [a, b] = testing::RunWithOneAndTwoThreads(testing::SlabModel(), GraspRun);
  EXPECT_TRUE(BitwiseEqual(a, b));
}

}  // namespace
}  // namespace arthrosim::instruments
