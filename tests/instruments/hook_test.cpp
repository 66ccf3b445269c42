// Hook on the slab scene's suture (fixed at x = 6, its end at x = 46): drawn up under the thread
// it snags it, pulls a loop out by the commanded distance while the thread runs through the
// bend, and lets it go when turned so that the pull points out of the bend, or when jerked away.
#include <gtest/gtest.h>

#include "arthrosim/core/parallel.h"
#include "arthrosim/physics/constraints.h"
#include "suture_scene.h"

namespace arthrosim::instruments {
namespace {

using testing::SlotDriver;

// Shaft down (tool +z = world -z), the hook's bend in the world y-z plane (tool x = world +y),
// across the thread (which runs along x): its mouth then opens up and toward +y.
Quat HookAcrossThread() { return testing::ToolAxes(Vec3(0, 1, 0), Vec3(1, 0, 0), Vec3(0, 0, -1)); }

std::int64_t HookId(const State& s) {
  const std::vector<std::int64_t> ids = physics::FindConstraintsByTag(s, "hook");
  return ids.empty() ? -1 : ids.front();
}

// The tool tip that puts the bend's seat at `seat` (world) with orientation q.
Vec3 TipFor(const Vec3& seat, const Quat& q, const Vec3& seat_local) {
  return seat - q * seat_local;
}

// Raises the hook under the thread at x = 36 (seat from 3 mm below it, 0.1 mm per step) until it
// snags; returns the constraint id (-1 if none within 40 steps). The seat in the tool frame is
// about (1.02, 0, -2.47) mm: the tip is placed for that and corrected from the constraint.
std::int64_t Snag(SlotDriver* d, Vec3* seat_local) {
  d->frame.tools[0].pose.orientation = HookAcrossThread();
  *seat_local = Vec3(1.023, 0, -2.470);
  const Quat q = HookAcrossThread();
  for (int k = 0; k < 3; ++k) d->Step(TipFor(Vec3(36, 10, 5), q, *seat_local), 0.0);
  for (int k = 1; k <= 40; ++k) {
    d->Step(TipFor(Vec3(36, 10, 5 + 0.1 * k), q, *seat_local), 0.0);
    if (HookId(*d->state) >= 0) {
      EXPECT_EQ(d->Events("hook_catch").size(), 1u);
      *seat_local = physics::FindConstraint(*d->state, HookId(*d->state))->a.offset_mm;
      return HookId(*d->state);
    }
  }
  return -1;
}

double WorstStrain(const State& s) {
  const Points& x = s.threads[0].x;
  double worst = 0;
  for (int n = 0; n + 1 < x.cols(); ++n)
    worst = std::max(worst, (x.col(n + 1) - x.col(n)).norm() - 1.0);
  return worst;
}

// `s` with an assistant's spring (tag "assistant") holding the suture's free end (node 40) at its
// place.
State WithFreeEndHeld(State s, double stiffness_n_per_mm) {
  SpringConstraint assistant;
  assistant.tag = "assistant";
  assistant.a = physics::ThreadPointEnd(0, 40);
  assistant.b.kind = ConstraintEnd::Kind::kWorld;
  assistant.b.offset_mm = Vec3(46, 10, 8);
  assistant.stiffness_n_per_mm = stiffness_n_per_mm;
  physics::AddConstraint(&s, assistant);
  return s;
}

// The slab scene with the hook snagged on the suture (Snag; id -1 if it did not) while an
// assistant holds the free end with the given stiffness.
struct SnaggedHook {
  explicit SnaggedHook(double assistant_n_per_mm)
      : s(WithFreeEndHeld(MakeInitialState(m), assistant_n_per_mm)),
        d(m, &s, "hook"),
        id(Snag(&d, &seat_local)) {}
  const Model m = testing::SlabModel();
  State s;
  SlotDriver d;
  Vec3 seat_local;
  std::int64_t id;
};

TEST(Hook, PullsALoopOutByTheCommandedDistanceAndLetsGoWhenTurned) {
  // An assistant holds the free end (0.5 N/mm), so the loop pulls on both limbs.
  SnaggedHook hook(0.5);
  auto& [m, s, d, seat_local, id] = hook;
  ASSERT_GE(id, 0) << "the thread was snagged";
  const Event caught = d.Events("hook_catch")[0];
  EXPECT_EQ(caught.body, "suture");
  EXPECT_NEAR(caught.position_mm.z(), 8.0, 0.3);
  // Draw the seat to 10 mm above the thread's line (z = 18) at 10 mm/s, then hold.
  const Quat q = HookAcrossThread();
  const Vec3 seat0 = s.tools[0].pose.Apply(seat_local);
  const Vec3 target(36, 10, 18);
  for (int k = 1; k <= 70; ++k) {
    const double f = std::min(1.0, k / 50.0);
    d.Step(TipFor(seat0 + f * (target - seat0), q, seat_local), 0.0);
    ASSERT_EQ(HookId(s), id) << "held at step " << k;
  }
  const SpringConstraint* c = physics::FindConstraint(s, id);
  const Vec3 held = physics::EndPosition(s, c->b);
  EXPECT_LT((held - target).norm(), 1.0) << "the thread point in the bend is at the seat";
  EXPECT_NEAR(held.z() - 8.0, 10.0, 1.0) << "the loop came out by the commanded 10 mm";
  EXPECT_GT(std::abs(physics::ThreadEndParameter(c->b) - 30.0), 0.5)
      << "the thread ran through the bend";
  EXPECT_LE(WorstStrain(s), 0.01);
  ASSERT_TRUE(s.threads[0].x.allFinite());
  // Turn the hook in its plane about the seat (about world x) until the mouth faces the pull.
  int released_at = -1;
  for (int k = 1; k <= 30 && released_at < 0; ++k) {
    const Quat turned =
        Quat(Eigen::AngleAxisd(k * 6.0 * 3.14159265358979 / 180, Vec3::UnitX())) * q;
    d.frame.tools[0].pose.orientation = turned;
    d.Step(TipFor(target, turned, seat_local), 0.0);
    if (!d.Events("hook_release").empty()) released_at = k;
  }
  ASSERT_GT(released_at, 0) << "released when turned";
  const std::string detail = d.Events("hook_release")[0].detail;
  EXPECT_NE(detail.find("reason=turned"), std::string::npos) << detail;
  EXPECT_EQ(HookId(s), -1);
  EXPECT_GT(released_at, 5) << "not before the mouth turned toward the pull";
}

TEST(Hook, LetsGoWhenTheThreadSlipsBeyondTheLimit) {
  // The free end held firmly (5 N/mm), so the thread cannot come along far.
  SnaggedHook hook(5);
  auto& [m, s, d, seat_local, id] = hook;
  ASSERT_GE(id, 0);
  // A 15 mm jerk up in one step: the loop would need 11.5 mm more thread, which the held end
  // gives only against tens of newtons (a 10 mm jerk leaves the thread 2.8 mm behind), so the
  // thread stays more than dist_limit (3 mm) behind.
  const Vec3 seat = s.tools[0].pose.Apply(seat_local);
  d.Step(TipFor(seat + Vec3(0, 0, 15), HookAcrossThread(), seat_local), 0.0);
  ASSERT_EQ(d.Events("hook_release").size(), 1u);
  EXPECT_NE(d.Events("hook_release")[0].detail.find("reason=distance"), std::string::npos)
      << d.Events("hook_release")[0].detail;
  EXPECT_EQ(physics::FindConstraint(s, id), nullptr);
}

TEST(Hook, BitIdenticalForOneAndTwoThreads) {
  const Model m = testing::SlabModel();
  const auto run = [&](int threads) {
    SetThreadCount(threads);
    State s = MakeInitialState(m);
    SlotDriver d(m, &s, "hook");
    Vec3 seat_local;
    Snag(&d, &seat_local);
    for (int k = 1; k <= 20; ++k)
      d.Step(TipFor(Vec3(36, 10, 6 + 0.3 * k), HookAcrossThread(), seat_local), 0.0);
    SetThreadCount(1);
    return s;
  };
  const State a = run(1), b = run(2);
  EXPECT_TRUE(BitwiseEqual(a, b));
  EXPECT_GE(HookId(a), 0);
}

}  // namespace
}  // namespace arthrosim::instruments
