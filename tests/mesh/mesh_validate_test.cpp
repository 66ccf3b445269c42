// Orientation fixing, degeneracy reporting, fatal index/coordinate errors and the volume
// formulas, checked against analytic volumes.
#include "arthrosim/mesh/mesh_validate.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "arthrosim/core/error.h"
#include "mesh_test_util.h"

namespace arthrosim::mesh {
namespace {

TetMesh UnitTet() {
  TetMesh m;
  m.nodes.resize(3, 4);
  m.nodes << 0, 1, 0, 0,  //
      0, 0, 1, 0,         //
      0, 0, 0, 1;
  m.tets = {{0, 1, 2, 3}};
  return m;
}

TEST(VolumeTest, UnitTetIsOneSixth) {
  const TetMesh m = UnitTet();
  EXPECT_DOUBLE_EQ(TetSignedVolume(m.nodes, m.tets[0]), 1.0 / 6.0);
  EXPECT_DOUBLE_EQ(TetSignedVolume(m.nodes, Tet{0, 2, 1, 3}), -1.0 / 6.0);
}

TEST(OrientTest, InvertedTetIsReorientedAndCounted) {
  TetMesh m = UnitTet();
  m.tets = {{0, 1, 2, 3}, {0, 2, 1, 3}, {1, 0, 2, 3}};
  const TetQualityReport r = OrientAndCheck(&m, "t");
  EXPECT_EQ(r.num_tets, 3);
  EXPECT_EQ(r.num_reoriented, 2);
  EXPECT_TRUE(r.degenerate.empty());
  EXPECT_EQ(m.tets[0], (Tet{0, 1, 2, 3}));  // untouched
  EXPECT_EQ(m.tets[1], (Tet{0, 2, 3, 1}));  // nodes 2 and 3 swapped
  for (const Tet& t : m.tets) EXPECT_DOUBLE_EQ(TetSignedVolume(m.nodes, t), 1.0 / 6.0);
  EXPECT_DOUBLE_EQ(r.total_volume, 0.5);
  EXPECT_DOUBLE_EQ(r.min_volume, 1.0 / 6.0);
}

TEST(OrientTest, KuhnCubeWithRandomInversionsRestoresTheExactVolume) {
  TetMesh m = testing::KuhnCube(3, 0.7);
  int flipped = 0;
  for (std::size_t i = 0; i < m.tets.size(); i += 3) {
    std::swap(m.tets[i][0], m.tets[i][1]);
    ++flipped;
  }
  const double v = std::pow(3 * 0.7, 3);
  EXPECT_LT(TotalVolume(m), v * 0.9);  // inverted tets subtract
  const TetQualityReport r = OrientAndCheck(&m, "cube");
  EXPECT_EQ(r.num_reoriented, flipped);
  EXPECT_NEAR(TotalVolume(m), v, 1e-12 * v);
  EXPECT_NEAR(r.total_volume, v, 1e-12 * v);
}

TEST(OrientTest, DegenerateTetsAreListedNotFatalAndScaleInvariant) {
  for (const double scale : {1e-3, 1.0, 1e4}) {
    TetMesh m;
    m.nodes.resize(3, 6);
    // Node 3 coplanar with 0,1,2 (exact zero volume); node 4 lifted 1e-13 L (below the 1e-12
    // threshold); node 5 lifted 1e-9 L (a thin but valid sliver).
    m.nodes << 0, 1, 0, 0.3, 0.3, 0.3,  //
        0, 0, 1, 0.3, 0.3, 0.3,         //
        0, 0, 0, 0, 1e-13, 1e-9;
    m.nodes *= scale;
    m.tets = {{0, 1, 2, 3}, {0, 1, 2, 4}, {0, 1, 2, 5}, {0, 2, 1, 5}};
    const TetQualityReport r = OrientAndCheck(&m, "deg");
    EXPECT_EQ(r.degenerate, (std::vector<std::int32_t>{0, 1})) << "scale " << scale;
    EXPECT_EQ(r.num_reoriented, 1) << "scale " << scale;  // only the sliver; degenerates untouched
    EXPECT_EQ(m.tets[1], (Tet{0, 1, 2, 4}));
  }
}

// OrientAndCheck throws on `m` an InputError naming `field`, its message holding `message`.
void ExpectOrientError(TetMesh m, const std::string& field, const std::string& message = "") {
  try {
    OrientAndCheck(&m, "f.msh");
    ADD_FAILURE() << "no error for " << field;
  } catch (const InputError& e) {
    EXPECT_EQ(e.field(), field);
    EXPECT_NE(std::string(e.what()).find(message), std::string::npos) << e.what();
  }
}

TEST(OrientTest, FatalProblemsNameTheElementOrNode) {
  TetMesh out_of_range = UnitTet();
  out_of_range.tets.push_back({0, 1, 2, 4});
  ExpectOrientError(out_of_range, "tet 1", "out of range [0, 4)");
  TetMesh repeated = UnitTet();
  repeated.tets.push_back({0, 1, 1, 3});
  ExpectOrientError(repeated, "tet 1", "appears twice");
  TetMesh infinite = UnitTet();
  infinite.nodes(1, 2) = std::numeric_limits<double>::infinity();
  ExpectOrientError(infinite, "node 2");
  TriMesh negative_index;
  negative_index.nodes = UnitTet().nodes;
  negative_index.tris = {{0, 1, -1}};
  EXPECT_THROW(OrientAndCheck(&negative_index, "f.obj"), InputError);
}

TEST(OrientTest, UnreferencedNodesAreCounted) {
  TetMesh m = UnitTet();
  m.nodes.conservativeResize(3, 6);
  m.nodes.col(4) = Vec3(5, 5, 5);
  m.nodes.col(5) = Vec3(6, 5, 5);
  EXPECT_EQ(OrientAndCheck(&m, "u").num_unreferenced_nodes, 2);
  // Put an unused node first: removal shifts the others down, keeping their order.
  TetMesh s;
  s.nodes.resize(3, 6);
  s.nodes.col(0) = Vec3(9, 9, 9);
  s.nodes.rightCols(5) = m.nodes.leftCols(5);
  s.tets = {{1, 2, 3, 4}};
  const std::vector<std::int32_t> map = RemoveUnreferencedNodes(&s);
  EXPECT_EQ(map, (std::vector<std::int32_t>{-1, 0, 1, 2, 3, -1}));
  EXPECT_EQ(s.nodes, UnitTet().nodes);
  EXPECT_EQ(s.tets, UnitTet().tets);
}

TriMesh CubeSurface(double a, const Vec3& shift) {
  TriMesh c;
  c.nodes.resize(3, 8);
  for (int i = 0; i < 8; ++i) {
    c.nodes.col(i) = shift + a * Vec3(i & 1, (i >> 1) & 1, (i >> 2) & 1);
  }
  c.tris = {{0, 2, 1}, {1, 2, 3}, {4, 5, 6}, {5, 7, 6}, {0, 1, 4}, {1, 5, 4},
            {2, 6, 3}, {3, 6, 7}, {0, 4, 2}, {2, 4, 6}, {1, 3, 5}, {3, 7, 5}};
  return c;
}

TEST(TriCheckTest, ClosedOutwardCubeEnclosesItsVolumeEvenFarFromTheOrigin) {
  for (const double far : {0.0, 1e4}) {
    TriMesh c = CubeSurface(2.5, Vec3(far, -far, 0.5 * far));
    const TriQualityReport r = OrientAndCheck(&c, "cube");
    EXPECT_TRUE(r.closed);
    EXPECT_TRUE(r.consistently_oriented);
    EXPECT_FALSE(r.flipped);
    EXPECT_NEAR(r.enclosed_volume, 15.625, 1e-9 * 15.625);
    EXPECT_NEAR(r.area, 6 * 6.25, 1e-9);
  }
}

TEST(TriCheckTest, InwardCubeIsFlippedOpenAndInconsistentAreReported) {
  TriMesh in = CubeSurface(1.0, Vec3::Zero());
  for (Tri& t : in.tris) std::swap(t[0], t[1]);
  EXPECT_DOUBLE_EQ(EnclosedVolume(in), -1.0);
  const TriQualityReport r = OrientAndCheck(&in, "in");
  EXPECT_TRUE(r.flipped);
  EXPECT_DOUBLE_EQ(EnclosedVolume(in), 1.0);

  TriMesh open = CubeSurface(1.0, Vec3::Zero());
  open.tris.pop_back();
  const TriQualityReport o = OrientAndCheck(&open, "open");
  EXPECT_FALSE(o.closed);
  EXPECT_FALSE(o.flipped);

  TriMesh mixed = CubeSurface(1.0, Vec3::Zero());
  std::swap(mixed.tris[3][0], mixed.tris[3][1]);
  const TriQualityReport m = OrientAndCheck(&mixed, "mixed");
  EXPECT_TRUE(m.closed);
  EXPECT_FALSE(m.consistently_oriented);

  TriMesh deg = CubeSurface(1.0, Vec3::Zero());
  deg.nodes.conservativeResize(3, 9);
  deg.nodes.col(8) = Vec3(0.5, 0, 0);  // on edge 0-1
  deg.tris.push_back({0, 8, 1});
  const TriQualityReport d = OrientAndCheck(&deg, "deg");
  EXPECT_EQ(d.degenerate, (std::vector<std::int32_t>{12}));
}

}  // namespace
}  // namespace arthrosim::mesh
