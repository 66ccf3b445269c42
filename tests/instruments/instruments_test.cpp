#include "arthrosim/instruments/instruments.h"

#include <gtest/gtest.h>

#include "arthrosim/io/scenario_loader.h"

namespace arthrosim::instruments {
namespace {

Model SmallModel() {
  return io::LoadScenario(std::string(ARTHROSIM_SOURCE_DIR) + "/tests/testdata/scenes/small.yaml");
}

TEST(Instruments, EmptySlotsLeaveTheStateUntouched) {
  const Model m = SmallModel();
  State s = MakeInitialState(m);
  const State before = s;
  InstrumentScratch scratch;
  ApplyInstruments(m, StepContext{}, &s, &scratch);
  EXPECT_TRUE(BitwiseEqual(before, s));
}

TEST(Instruments, EventsCarryTheStepTheToolAndThePosition) {
  const Model m = SmallModel();
  State s = MakeInitialState(m);
  s.step = 7;
  s.time_s = 7 * m.options.dt_s;
  s.tools[1].instrument = m.FindInstrument("grasper");
  ASSERT_GE(s.tools[1].instrument, 0);
  RecordEvent(m, 1, "cut", "tendon", "tets=3", Vec3(1, 2, 3), &s);
  ASSERT_EQ(s.events.size(), 1u);
  const Event& e = s.events[0];
  EXPECT_EQ(e.step, 7);
  EXPECT_EQ(e.time_s, 7 * m.options.dt_s);
  EXPECT_EQ(e.kind, "cut");
  EXPECT_EQ(e.tool, "grasper");
  EXPECT_EQ(e.body, "tendon");
  EXPECT_EQ(e.detail, "tets=3");
  EXPECT_EQ(e.position_mm, Vec3(1, 2, 3));
}

}  // namespace
}  // namespace arthrosim::instruments
