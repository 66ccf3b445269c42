// A steady-state collision stage makes no heap allocation (project convention): the global
// operator new is counted in this test binary while Detect runs on the benchmark scene with two
// tools sweeping across the tissue and a travelling wave on the soft bodies.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <new>

#include "../support/counting_new.h"
#include "arthrosim/collision/bench_scene.h"
#include "arthrosim/collision/contact_generation.h"
#include "arthrosim/core/units.h"

namespace arthrosim::collision {
namespace {

TEST(CollisionAllocation, SteadyStateDetectDoesNotAllocate) {
  if (!test_support::kCountingNew)
    GTEST_SKIP() << "allocation counting is off under AddressSanitizer";
  const Model model = MakeBenchmarkModel();
  State state = MakeInitialState(model);
  std::vector<Points> rest;
  for (const SoftBodyState& b : state.soft_bodies) rest.push_back(b.x);
  const Quat down(Eigen::AngleAxisd(units::kPi, Vec3::UnitX()));
  CollisionParams params;
  CollisionWorld world;
  CollisionOutput out;
  long steady = 0;
  std::size_t contacts = 0;
  for (int step = 0; step < 40; ++step) {
    const auto prev = state.tools;
    for (int slot = 0; slot < kToolSlots; ++slot) {
      ToolState& t = state.tools[slot];
      t.instrument = slot;
      t.pose.orientation = down;
      // Back and forth across the tissue top (z 29 in the benchmark model) at 100 mm/s.
      const double y = 6.0 * std::sin(0.33 * step) * (slot == 0 ? 1 : -1);
      t.pose.position_mm = Vec3(slot == 0 ? -8.0 : 8.0, y, 28.7);
      t.jaw = 0.5 + 0.5 * std::sin(0.1 * step);
    }
    for (std::size_t b = 0; b < rest.size(); ++b) {
      for (Eigen::Index i = 0; i < rest[b].cols(); ++i) {
        state.soft_bodies[b].x(2, i) =
            rest[b](2, i) + 0.3 * std::sin(0.2 * rest[b](0, i) + 0.3 * step);
      }
    }
    const long before = test_support::AllocationCount();
    Detect(model, state, step == 0 ? state.tools : prev, params, &world, &out);
    if (step >= 20) {
      steady += test_support::AllocationCount() - before;
      contacts += out.contacts.size();
    }
  }
  std::printf("allocations in steps 20-39: %ld (%zu contacts)\n", steady, contacts);
  EXPECT_GT(contacts, 20u * 20u);  // the tools really work on the tissue
  EXPECT_EQ(steady, 0);
}

}  // namespace
}  // namespace arthrosim::collision
