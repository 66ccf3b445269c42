#include "arthrosim/sim/step.h"

#include <gtest/gtest.h>

#include "arthrosim/core/error.h"
#include "arthrosim/core/parallel.h"
#include "arthrosim/io/scenario_loader.h"
#include "arthrosim/physics/constraints.h"

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

// A runtime constraint from the grasper (slot 0) to the thread's free end: the thread follows the
// tool, and the tool feels the spring's pull back (haptic feedback) — equal and opposite.
TEST(StepTest, ToolHeldConstraintPullsTheThreadAndFeedsBackItsForce) {
  const Model m = SmallModel();
  State s = MakeInitialState(m);
  Workspace ws;
  BuildWorkspace(m, s, &ws);
  SpringConstraint grasp;
  grasp.tag = "hold";  // not "grasp": the grasper operation would release it (jaw open)
  grasp.a.kind = ConstraintEnd::Kind::kTool;
  grasp.a.index = 0;
  grasp.b = physics::ThreadPointEnd(0, 10);  // node 10 of thread 0
  grasp.stiffness_n_per_mm = 0.5;
  physics::AddConstraint(&s, grasp);
  InputFrame f;
  f.camera.pose = m.camera.initial_pose;
  f.tools[0].instrument = m.FindInstrument("grasper");
  for (int k = 1; k <= 50; ++k) {
    f.tools[0].pose.position_mm = Vec3(20.0 + 0.2 * k, 0, 40);  // up and away from the thread end
    Step(m, f, &s, &ws);
  }
  const Vec3 tip = s.tools[0].pose.position_mm;
  const Vec3 end = s.threads[0].x.col(10);
  // the free end was lifted from z = 30 toward the tool at z = 40
  EXPECT_GT(end.z(), 32.0);
  // the tool is pulled toward the thread end, with the spring's force k * stretch (N)
  const Vec3 expected = grasp.stiffness_n_per_mm * (end - tip);
  EXPECT_GT(s.tools[0].force_n.norm(), 0.1);
  EXPECT_LT((s.tools[0].force_n - expected).norm(), 0.02 * expected.norm() + 1e-6);
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

// The workspace's solver settings are the Model's options (one place: core/model.h).
TEST(StepTest, WorkspaceTakesTheContactAndThreadSolverOptionsOfTheModel) {
  Model m = SmallModel();
  m.contact.bone_tip_contacts = false;
  m.contact.alarm_distance_mm = 0.8;
  m.thread_solver.max_strain = 0.03;
  m.thread_solver.contact_stiffness_n_per_mm = 40;
  const State s = MakeInitialState(m);
  Workspace ws;
  BuildWorkspace(m, s, &ws);
  EXPECT_FALSE(ws.collision_params.bone_tip_contacts);
  EXPECT_EQ(ws.collision_params.alarm_distance_mm, 0.8);
  EXPECT_EQ(ws.threads.params.max_strain, 0.03);
  EXPECT_EQ(ws.threads.params.contact_stiffness_n_per_mm, 40.0);
}

}  // namespace
}  // namespace arthrosim::sim
