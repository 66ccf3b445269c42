#include "arthrosim/sim/step.h"

#include <gtest/gtest.h>

#include "arthrosim/core/error.h"
#include "arthrosim/core/parallel.h"
#include "arthrosim/io/scenario_loader.h"

namespace arthrosim::sim {
namespace {

Model SmallModel() {
  return io::LoadScenario(std::string(ARTHROSIM_SOURCE_DIR) + "/tests/testdata/scenes/small.yaml");
}

// A grasper moving along x through slot 0, the scope still, from step 1 on.
InputFrame Input(const Model& m, std::int64_t step) {
  InputFrame f;
  f.camera.pose = m.camera.initial_pose;
  f.tools[0].instrument = step >= 3 ? m.FindInstrument("grasper") : -1;
  f.tools[0].pose.position_mm = Vec3(40.0 - 0.5 * static_cast<double>(step), 10, 12);
  f.tools[0].jaw = step >= 8 ? 1.0 : 0.0;
  return f;
}

State RunSteps(const Model& m, State s, std::int64_t steps) {
  Workspace ws;
  BuildWorkspace(m, s, &ws);
  for (std::int64_t k = 0; k < steps; ++k) Step(m, Input(m, s.step + 1), &s, &ws);
  return s;
}

TEST(StepTest, GravityPullsTheFreeSideDownAndTimeAdvances) {
  const Model m = SmallModel();
  const State s0 = MakeInitialState(m);
  const State s = RunSteps(m, s0, 10);
  EXPECT_EQ(s.step, 10);
  EXPECT_DOUBLE_EQ(s.time_s, 10 * m.options.dt_s);
  const Points& x = s.soft_bodies[0].x;
  ASSERT_TRUE(x.allFinite());
  // Fixed base nodes stay put; the top sags.
  EXPECT_EQ(x.col(0), s0.soft_bodies[0].x.col(0));
  EXPECT_LT(x(2, 7), s0.soft_bodies[0].x(2, 7));
  // The thread's free end falls, its fixed node stays.
  EXPECT_EQ(s.threads[0].x.col(0), s0.threads[0].x.col(0));
  EXPECT_LT(s.threads[0].x(2, 10), s0.threads[0].x(2, 10));
}

TEST(StepTest, InstrumentExchangeIsAnEvent) {
  const Model m = SmallModel();
  State s = MakeInitialState(m);
  Workspace ws;
  BuildWorkspace(m, s, &ws);
  auto tool_changes = [&s] {
    std::vector<Event> out;
    for (const Event& e : s.events) {
      if (e.kind == "tool_change") out.push_back(e);
    }
    return out;
  };
  for (int k = 1; k <= 3; ++k) Step(m, Input(m, k), &s, &ws);
  ASSERT_EQ(tool_changes().size(), 1u);
  EXPECT_EQ(tool_changes()[0].tool, "grasper");
  EXPECT_EQ(tool_changes()[0].step, 3);  // the step from 2 to 3: belongs to state 3
  EXPECT_EQ(s.tools[0].instrument, m.FindInstrument("grasper"));
  Step(m, Input(m, 4), &s, &ws);
  EXPECT_TRUE(tool_changes().empty());
}

TEST(StepTest, BitIdenticalForOneAndTwoThreads) {
  const Model m = SmallModel();
  SetThreadCount(1);
  const State a = RunSteps(m, MakeInitialState(m), 20);
  SetThreadCount(2);
  const State b = RunSteps(m, MakeInitialState(m), 20);
  SetThreadCount(1);
  EXPECT_TRUE(BitwiseEqual(a, b));
  EXPECT_EQ(HashState(a), HashState(b));
}

TEST(StepTest, RestoreAndContinueEqualsAnUninterruptedRun) {
  const Model m = SmallModel();
  const State straight = RunSteps(m, MakeInitialState(m), 20);
  const State half = RunSteps(m, MakeInitialState(m), 10);
  const State saved = half;  // a copy is a save; a fresh Workspace is a restore
  const State resumed = RunSteps(m, saved, 10);
  EXPECT_TRUE(BitwiseEqual(straight, resumed));
}

TEST(StepTest, BadInstrumentIndexIsAnInputError) {
  const Model m = SmallModel();
  State s = MakeInitialState(m);
  Workspace ws;
  BuildWorkspace(m, s, &ws);
  InputFrame f = Input(m, 1);
  f.tools[1].instrument = 99;
  EXPECT_THROW(Step(m, f, &s, &ws), InputError);
}

}  // namespace
}  // namespace arthrosim::sim
