#include "arthrosim/core/soft_nodes.h"

#include <gtest/gtest.h>

namespace arthrosim {
namespace {

// Two tets sharing the face (1, 2, 3); node 4 belongs to the second only, node 5 to none.
SoftBodyState TwoTets() {
  SoftBodyState b;
  b.x = Points::Zero(3, 6);
  b.tets = {mesh::Tet{0, 1, 2, 3}, mesh::Tet{1, 2, 3, 4}};
  b.tet_alive = {1, 1};
  return b;
}

TEST(SoftNodes, NodesOfAliveTetsOnly) {
  SoftBodyState b = TwoTets();
  EXPECT_EQ(NodesInAliveTets(b), (std::vector<std::uint8_t>{1, 1, 1, 1, 1, 0}));
  b.tet_alive[1] = 0;  // the second tet cut away: node 4 is debris, the shared face stays
  EXPECT_EQ(NodesInAliveTets(b), (std::vector<std::uint8_t>{1, 1, 1, 1, 0, 0}));
  b.tet_alive[0] = 0;
  EXPECT_EQ(NodesInAliveTets(b), (std::vector<std::uint8_t>(6, 0)));
}

}  // namespace
}  // namespace arthrosim
