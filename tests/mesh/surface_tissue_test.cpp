// Tissue labels of a bone surface carried over to a reshaped surface (mesh/surface_tissue.h).
#include "arthrosim/mesh/surface_tissue.h"

#include <gtest/gtest.h>

#include <vector>

namespace arthrosim::mesh {
namespace {

// Two unit squares side by side in z = 0 (x in [0, 2]), two triangles each: triangles 0, 1 over
// x in [0, 1] are tissue 0, triangles 2, 3 over x in [1, 2] bone.
TriMesh Strip() {
  TriMesh m;
  m.nodes.resize(3, 6);
  m.nodes << 0, 1, 2, 0, 1, 2,  //
      0, 0, 0, 1, 1, 1,         //
      0, 0, 0, 0, 0, 0;
  m.tris = {{0, 1, 4}, {0, 4, 3}, {1, 2, 5}, {1, 5, 4}};
  return m;
}

TEST(SurfaceTissue, NearestInitialCentroidDecides) {
  const TriMesh m = Strip();
  const std::vector<std::int8_t> labels = {0, 0, kBoneTissue, kBoneTissue};
  EXPECT_EQ(TissueNear(m, labels, Vec3(0.3, 0.5, -0.8)), 0);  // below the tissue, burred into
  EXPECT_EQ(TissueNear(m, labels, Vec3(1.7, 0.5, 0.0)), kBoneTissue);
  EXPECT_EQ(TissueNear(m, {}, Vec3(0.3, 0.5, 0.0)), kBoneTissue);  // no tissues
}

TEST(SurfaceTissue, KeptTrianglesKeepTheirLabelAppendedOnesTakeTheNearest) {
  const TriMesh initial = Strip();
  const std::vector<std::int8_t> labels = {0, 0, kBoneTissue, kBoneTissue};
  // a carve: split the edge (0, 4) of triangles 0 and 1 (halves replace them in place, the
  // other halves are appended), then split edge (1, 5) of triangle 2 likewise, and sink the
  // midpoints 0.5 mm
  TriMesh now = initial;
  now.nodes.conservativeResize(3, 8);
  now.nodes.col(6) = Vec3(0.5, 0.5, -0.5);
  now.nodes.col(7) = Vec3(1.5, 0.5, -0.5);
  now.tris[0] = {0, 1, 6};
  now.tris[1] = {0, 6, 3};
  now.tris.push_back({6, 1, 4});
  now.tris.push_back({6, 4, 3});
  now.tris[2] = {1, 2, 7};
  now.tris.push_back({7, 2, 5});
  const std::vector<std::int8_t> got = TriangleTissues(initial, labels, now);
  const std::vector<std::int8_t> want = {0, 0, kBoneTissue, kBoneTissue, 0, 0, kBoneTissue};
  EXPECT_EQ(got, want);
  // unchanged topology: the labels as they are
  EXPECT_EQ(TriangleTissues(initial, labels, initial), labels);
  EXPECT_EQ(TriangleTissues(initial, {}, now), std::vector<std::int8_t>(now.tris.size(), -1));
}

}  // namespace
}  // namespace arthrosim::mesh
