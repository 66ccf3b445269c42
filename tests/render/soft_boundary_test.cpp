#include "soft_boundary.h"

#include <gtest/gtest.h>

#include <map>

#include "test_scene.h"

namespace arthrosim::render {
namespace {

using testing::FiveTetCube;

// Closed and consistently oriented: every directed edge is matched by as many reversed ones
// (more than one pair at edges where only corners of tets touch, after a cut).
bool ClosedAndConsistent(const std::vector<mesh::Tri>& tris) {
  std::map<std::pair<int, int>, int> directed;
  for (const mesh::Tri& t : tris) {
    for (int k = 0; k < 3; ++k) ++directed[{t[k], t[(k + 1) % 3]}];
  }
  for (const auto& [edge, count] : directed) {
    auto it = directed.find({edge.second, edge.first});
    if (it == directed.end() || it->second != count) return false;
  }
  return true;
}

// Signed volume enclosed by the surface: > 0 when the faces point outward.
double EnclosedVolume(const Points& x, const std::vector<mesh::Tri>& tris) {
  double v = 0;
  for (const mesh::Tri& t : tris) v += x.col(t[0]).dot(x.col(t[1]).cross(x.col(t[2]))) / 6.0;
  return v;
}

TEST(AliveBoundaryTest, SingleTetGivesFourOutwardFaces) {
  Points x(3, 4);
  x << 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1;
  const auto tris = AliveBoundary({{0, 1, 2, 3}}, {});
  ASSERT_EQ(tris.size(), 4u);
  EXPECT_TRUE(ClosedAndConsistent(tris));
  EXPECT_NEAR(EnclosedVolume(x, tris), 1.0 / 6.0, 1e-12);
}

TEST(AliveBoundaryTest, SharedFaceIsInterior) {
  const mesh::TetMesh cube = FiveTetCube(Vec3::Zero(), 2.0);
  const auto tris = AliveBoundary(cube.tets, {});
  EXPECT_EQ(tris.size(), 12u);  // two triangles per cube face
  EXPECT_TRUE(ClosedAndConsistent(tris));
  EXPECT_NEAR(EnclosedVolume(cube.nodes, tris), 8.0, 1e-12);
}

TEST(AliveBoundaryTest, RemovedTetExposesTheCutSurface) {
  const mesh::TetMesh cube = FiveTetCube(Vec3::Zero(), 2.0);
  // remove the central tet: its 4 faces become boundary of the 4 corner tets
  const auto tris = AliveBoundary(cube.tets, {1, 1, 1, 1, 0});
  EXPECT_EQ(tris.size(), 16u);
  EXPECT_TRUE(ClosedAndConsistent(tris));
  EXPECT_NEAR(EnclosedVolume(cube.nodes, tris), 8.0 - 8.0 / 3.0, 1e-12);
  // remove a corner tet instead: a notch, still closed
  const auto notch = AliveBoundary(cube.tets, {0, 1, 1, 1, 1});
  EXPECT_EQ(notch.size(), 10u);
  EXPECT_TRUE(ClosedAndConsistent(notch));
  EXPECT_NEAR(EnclosedVolume(cube.nodes, notch), 8.0 - 8.0 / 6.0, 1e-12);
}

TEST(AliveBoundaryTest, AllDeadGivesNothing) {
  const mesh::TetMesh cube = FiveTetCube(Vec3::Zero(), 1.0);
  EXPECT_TRUE(AliveBoundary(cube.tets, {0, 0, 0, 0, 0}).empty());
}

}  // namespace
}  // namespace arthrosim::render
