// The whole step makes no heap allocation in steady state (project convention): the global
// operator new is counted in this test binary while two instruments work on the cuff of the
// benchmark scene with its two suture threads. Steps that record a discrete event may allocate
// (an event carries text); every other step must not.
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <new>
#include <string>

#include "../support/counting_new.h"
#include "arthrosim/io/scenario_loader.h"
#include "arthrosim/sim/step.h"

namespace arthrosim::sim {
namespace {

// Two instruments sweep back and forth across the tendon (tips 0.5 mm into it, 2 mm per step)
// with a period of 40 steps while the two threads settle on the tissue: after two periods every
// work list has reached its size, and the third period must not allocate.
TEST(StepAllocation, PeriodicToolWorkDoesNotAllocate) {
  if (!test_support::kCountingNew)
    GTEST_SKIP() << "allocation counting is off under AddressSanitizer";
  const Model model =
      io::LoadScenario(std::string(ARTHROSIM_SOURCE_DIR) + "/scenarios/bench_full.yaml");
  const int tendon = model.FindSoftBody("supraspinatus_tendon");
  ASSERT_GE(tendon, 0);
  State state = MakeInitialState(model);
  const Points& rest = state.soft_bodies[static_cast<std::size_t>(tendon)].x;
  const Vec3 lo = rest.rowwise().minCoeff(), hi = rest.rowwise().maxCoeff();
  const Vec3 mid = 0.5 * (lo + hi);
  const std::array<int, kToolSlots> tools{model.FindInstrument("shaver"),
                                          model.FindInstrument("electrocautery")};
  ASSERT_GE(tools[0], 0);
  ASSERT_GE(tools[1], 0);
  Workspace ws;
  BuildWorkspace(model, state, &ws);
  long allocations = 0;
  int counted = 0, contact_steps = 0;
  for (int k = 0; k < 120; ++k) {
    InputFrame frame;
    frame.camera.pose = model.camera.initial_pose;
    const int phase = k % 40;  // triangle wave: 20 steps out, 20 back
    const double w = -20.0 + 2.0 * (phase < 20 ? phase : 40 - phase);  // mm
    for (int slot = 0; slot < kToolSlots; ++slot) {
      ToolCommand& t = frame.tools[static_cast<std::size_t>(slot)];
      t.instrument = tools[static_cast<std::size_t>(slot)];
      const double x = mid.x() + (slot == 0 ? -0.25 : 0.25) * (hi.x() - lo.x());
      t.pose.position_mm = Vec3(x, mid.y() + (slot == 0 ? w : -w), hi.z() - 0.5);
      t.pose.orientation = Quat(Eigen::AngleAxisd(3.14159265358979323846, Vec3::UnitX()));
    }
    const long before = test_support::AllocationCount();
    Step(model, frame, &state, &ws);
    const long n = test_support::AllocationCount() - before;
    if (k < 80 || !state.events.empty()) continue;  // two periods to size; events carry text
    ++counted;
    allocations += n;
    if (!ws.contacts.contacts.empty()) ++contact_steps;
    if (n != 0) std::printf("step %lld: %ld allocations\n", static_cast<long long>(state.step), n);
  }
  std::printf("%d counted steps (%d with contacts): %ld allocations\n", counted, contact_steps,
              allocations);
  EXPECT_GT(counted, 20);
  EXPECT_EQ(contact_steps, counted);  // the tools really work on the tissue
  EXPECT_EQ(allocations, 0);
}

}  // namespace
}  // namespace arthrosim::sim
