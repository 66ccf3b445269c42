// A steady-state soft-tissue step makes no heap allocation (project convention), including the
// steps that refactor the preconditioner: the global operator new is counted in this test binary
// while a spring drags the cuff of the benchmark scenario around a circle.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <new>
#include <string>

#include "../support/counting_new.h"
#include "arthrosim/io/scenario_loader.h"
#include "arthrosim/physics/soft_system.h"

namespace arthrosim::physics {
namespace {

TEST(SoftAllocation, SteadyStateStepsIncludingRefactorsDoNotAllocate) {
  if (!test_support::kCountingNew)
    GTEST_SKIP() << "allocation counting is off under AddressSanitizer";
  const Model model =
      io::LoadScenario(std::string(ARTHROSIM_SOURCE_DIR) + "/scenarios/bench_full.yaml");
  State state = MakeInitialState(model);
  SoftSystem sys;
  sys.Build(model, state);
  // A grasper-like spring on a free tendon node, dragged 4 mm around a circle in 0.4 s.
  const int body = static_cast<int>(model.soft_bodies.size()) - 1;  // the tendon
  std::int32_t node = 0;
  while (!sys.IsFree(body, node)) ++node;
  const Vec3 centre = state.soft_bodies[static_cast<std::size_t>(body)].x.col(node);
  SpringSet springs(1);
  springs[0].index = body;
  springs[0].nodes = {node, -1, -1, -1};
  springs[0].weights = {1, 0, 0, 0};
  springs[0].stiffness_n_per_mm = 0.5;
  long steady = 0;
  int refactors = 0, iterations = 0;
  for (int k = 0; k < 80; ++k) {
    const double phase = 2.0 * 3.14159265358979323846 * k * model.options.dt_s / 0.4;
    springs[0].anchor_mm = centre + 4.0 * Vec3(0, std::sin(phase), 1.0 - std::cos(phase));
    const long before = test_support::AllocationCount();
    const SoftStepStats st = sys.Step(model, nullptr, &springs, &state);
    ++state.step;  // as the sim layer does: a requested factor is used lag steps later
    if (k >= 20) {
      steady += test_support::AllocationCount() - before;
      refactors += st.refactored ? 1 : 0;
      iterations += st.cg_iterations;
    }
  }
  std::printf("allocations in steps 20-79: %ld (%d refactors, %d CG iterations)\n", steady,
              refactors, iterations);
  EXPECT_GT(refactors, 0);  // the refactor path is exercised in the counted steps
  EXPECT_GT(iterations, 60);
  EXPECT_EQ(steady, 0);
}

}  // namespace
}  // namespace arthrosim::physics
