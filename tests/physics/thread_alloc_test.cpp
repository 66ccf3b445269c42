// StepThreads must not allocate in a steady-state step (project rule: scratch lives in the
// workspace). A counting global operator new in this executable sees every heap allocation.
#include <gtest/gtest.h>

#include <atomic>
#include <cstdlib>
#include <new>
#include <vector>

#include "../support/counting_new.h"
#include "arthrosim/core/units.h"
#include "arthrosim/physics/thread_chain.h"
#include "thread_test_util.h"

namespace arthrosim::physics {
namespace {

using testing::PolylineThread;
using testing::RestState;

TEST(ThreadAllocation, CounterSeesAllocations) {
  if (!test_support::kCountingNew)
    GTEST_SKIP() << "allocation counting is off under AddressSanitizer";
  const long before = test_support::AllocationCount();
  std::vector<double>* v = new std::vector<double>(100, 1.0);
  const long after = test_support::AllocationCount();
  delete v;
  EXPECT_GE(after - before, 2);  // the vector object and its buffer
}

// Two crossing threads falling onto a floor (point contacts), one pulled by a spring, with
// self- and thread-thread contacts: every stage of the step runs.
// With adaptive substeps (max_substep_levels 2), the split steps do not allocate either.
void SteadyState(int substep_levels) {
  ThreadModel a = PolylineThread({{0, 0, 1}, {30, 0, 1}}, 40);
  a.fixed_nodes = {0};
  a.bend_stiffness_n_mm2 = 0.5;
  ThreadModel b = PolylineThread({{15, -15, 2}, {15, 15, 2}}, 30);
  b.name.assign(1, 'b');  // not = "b": GCC 12 -Wrestrict false positive
  b.fixed_nodes = {0};
  std::vector<ThreadModel> models{a, b};
  std::vector<ThreadState> states{RestState(a), RestState(b)};
  ThreadWorkspace ws;
  InitThreadWorkspace(models, &ws);
  ws.params.max_substep_levels = substep_levels;
  ContactSet floor;
  for (int t = 0; t < 2; ++t) {
    for (int i = 0; i < states[t].x.cols(); ++i) floor.push_back(testing::FloorContact(t, i, 10));
  }
  SpringSet springs{testing::NodeSpring(1, 30, 2)};
  const Vec3 gravity(0, 0, -units::kStandardGravityMmS2);
  long allocations = 0;
  int pairs = 0, iterations = 0, substeps = 0;
  for (int step = 0; step < 60; ++step) {
    springs[0].anchor_mm = Vec3(15 + 5 * std::sin(0.1 * step), 15, 3);
    const long before = test_support::AllocationCount();
    StepThreads(models, 0.02, gravity, &floor, &springs, &states, &ws);
    if (step > 0) allocations += test_support::AllocationCount() - before;
    pairs = std::max(pairs, ws.last.contact_pairs);
    iterations += ws.last.newton_iterations;
    substeps += ws.last.substeps;
  }
  EXPECT_EQ(allocations, 0) << "heap allocations in 59 steady-state steps";
  EXPECT_GT(pairs, 0) << "the scene should exercise thread-thread contacts";
  if (substep_levels > 0) {
    EXPECT_GT(substeps, 60) << "the scene should split steps";
  }
  std::printf(
      "substep levels %d: allocations after step 0: %ld; max contact pairs %d; Newton iterations "
      "%d; substeps %d\n",
      substep_levels, allocations, pairs, iterations, substeps);
}

TEST(ThreadAllocation, SteadyStateStepDoesNotAllocate) {
  if (!test_support::kCountingNew)
    GTEST_SKIP() << "allocation counting is off under AddressSanitizer";
  SteadyState(0);
}

TEST(ThreadAllocation, SteadyStateSubstepsDoNotAllocate) {
  if (!test_support::kCountingNew)
    GTEST_SKIP() << "allocation counting is off under AddressSanitizer";
  SteadyState(2);
}

}  // namespace
}  // namespace arthrosim::physics
