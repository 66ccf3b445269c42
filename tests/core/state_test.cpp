#include "arthrosim/core/state.h"

#include <gtest/gtest.h>

#include "arthrosim/core/model.h"

namespace arthrosim {
namespace {

Model TinyModel() {
  Model m;
  SoftBodyModel b;
  b.name = "block";
  b.rest_mesh.nodes = Points(3, 4);
  b.rest_mesh.nodes << 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1;
  b.rest_mesh.tets = {{0, 1, 2, 3}};
  m.soft_bodies.push_back(b);
  m.options.seed = 42;
  return m;
}

TEST(StateTest, InitialStateIsAtRestAndAlive) {
  const State s = MakeInitialState(TinyModel());
  ASSERT_EQ(s.soft_bodies.size(), 1u);
  EXPECT_EQ(s.soft_bodies[0].x, s.soft_bodies[0].x_rest);
  EXPECT_TRUE(s.soft_bodies[0].v.isZero());
  EXPECT_EQ(s.soft_bodies[0].tet_alive, std::vector<std::uint8_t>{1});
  EXPECT_EQ(s.rng_state, 42u);
}

TEST(StateTest, EqualityAndHashSeeEveryBit) {
  const State a = MakeInitialState(TinyModel());
  State b = a;
  EXPECT_TRUE(BitwiseEqual(a, b));
  EXPECT_EQ(HashState(a), HashState(b));
  b.soft_bodies[0].x(2, 3) = std::nextafter(1.0, 2.0);
  EXPECT_FALSE(BitwiseEqual(a, b));
  EXPECT_NE(HashState(a), HashState(b));
  b = a;
  b.events.push_back(Event{0, 0.0, "cut", "scissors", "block", "", Vec3::Zero()});
  EXPECT_FALSE(BitwiseEqual(a, b));
  b = a;
  b.tools[1].buttons = 2;
  EXPECT_NE(HashState(a), HashState(b));
}

}  // namespace
}  // namespace arthrosim
