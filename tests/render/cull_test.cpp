#include "cull.h"

#include <gtest/gtest.h>

#include <memory>

#include "surface_cache.h"
#include "test_scene.h"

namespace arthrosim::render {
namespace {

// Sphere of radius 10 mm at the origin as a SceneMesh with its closed flag set as BuildScene does.
SceneMesh Sphere(bool inward = false) {
  const mesh::TriMesh tri = testing::UvSphere(Vec3::Zero(), 10.0, 12);
  SceneMesh m;
  for (Eigen::Index n = 0; n < tri.nodes.cols(); ++n) {
    Vertex v{};
    for (int k = 0; k < 3; ++k) v.pos[k] = static_cast<float>(tri.nodes(k, n));
    m.vertices.push_back(v);
  }
  for (const mesh::Tri& t : tri.tris) {
    m.indices.push_back(t[0]);
    m.indices.push_back(inward ? t[2] : t[1]);
    m.indices.push_back(inward ? t[1] : t[2]);
  }
  m.closed = IsClosedSurface(m.indices) && SignedVolume(m) > 0;
  return m;
}

TEST(CullTest, ClosedOutwardSurfaceIsRecognised) {
  EXPECT_TRUE(Sphere().closed);
  EXPECT_GT(SignedVolume(Sphere()), 0.9 * 4.0 / 3.0 * testing::kPi * 1000 * 0.8);
  EXPECT_FALSE(Sphere(true).closed);  // inside out: negative volume
  SceneMesh open = Sphere();
  open.indices.resize(open.indices.size() - 3);  // one triangle missing
  EXPECT_FALSE(IsClosedSurface(open.indices));
  std::vector<std::uint32_t> twice = Sphere().indices;
  twice.insert(twice.end(), twice.begin(), twice.begin() + 3);  // a duplicated triangle
  EXPECT_FALSE(IsClosedSurface(twice));
  EXPECT_FALSE(IsClosedSurface({0, 0, 1, 1, 0, 0}));  // degenerate
  EXPECT_FALSE(IsClosedSurface({}));
}

TEST(CullTest, BackFacesHiddenOnlyFromOutsideBeyondTheNearPlane) {
  const SceneMesh s = Sphere();
  EXPECT_TRUE(BackFacesHidden(s, Vec3(0, 0, 30), 1.0));
  EXPECT_TRUE(BackFacesHidden(s, Vec3(8, 8, 8), 1.0));      // in the box, outside the sphere
  EXPECT_FALSE(BackFacesHidden(s, Vec3(0, 0, 0), 1.0));     // inside
  EXPECT_FALSE(BackFacesHidden(s, Vec3(1, 2, -3), 1.0));    // inside
  EXPECT_FALSE(BackFacesHidden(s, Vec3(0, 0, 10.5), 1.0));  // near plane could cut the cap
  EXPECT_TRUE(BackFacesHidden(s, Vec3(0, 0, 11.5), 1.0));
  SceneMesh open = s;
  open.closed = false;
  EXPECT_FALSE(BackFacesHidden(open, Vec3(0, 0, 30), 1.0));
}

// A bone's tissue part (here the upper half of the sphere, an open surface) is culled as its
// closed whole is: from outside beyond the near plane, not from inside; without the whole it
// never is (an open surface alone may show its back faces).
TEST(CullTest, AnOpenPartOfAClosedSurfaceIsCulledAsTheWholeIs) {
  const auto whole = std::make_shared<const SceneMesh>(Sphere());
  SceneMesh part;
  part.vertices = whole->vertices;
  for (std::size_t t = 0; t + 2 < whole->indices.size(); t += 3) {
    if (whole->vertices[whole->indices[t]].pos[2] < 0) continue;
    for (std::size_t k = t; k < t + 3; ++k) part.indices.push_back(whole->indices[k]);
  }
  ASSERT_FALSE(IsClosedSurface(part.indices));
  // Decided as the renderer does: on the part alone, or on its whole with the whole's box.
  const auto cull = [&](const SceneMesh& m, const Vec3& eye) {
    return m.whole ? CullBackFaces(*m.whole, MeshBox(*m.whole), eye, 1.0)
                   : CullBackFaces(m, MeshBox(m), eye, 1.0);
  };
  EXPECT_FALSE(cull(part, Vec3(0, 0, 30)));
  part.whole = whole;
  EXPECT_TRUE(cull(part, Vec3(0, 0, 30)));
  EXPECT_TRUE(cull(part, Vec3(0, 0, -30)));  // the part's far side
  EXPECT_FALSE(cull(part, Vec3(1, 2, -3)));  // inside the whole
  EXPECT_FALSE(cull(part, Vec3(0, 0, 10.5)));
}

TEST(CullTest, SoftBodyBoundaryIsClosedUnlessTurnedInsideOut) {
  Model model;
  State state = testing::MakeTestScene(&model);
  const Scene scene = BuildScene(model, state);
  for (const SceneMesh& m : scene.meshes) {
    if (m.layer == MeshLayer::kSoftTissue || m.layer == MeshLayer::kBone) {
      EXPECT_TRUE(m.closed) << m.name;
    }
  }
  state.soft_bodies[0].x.row(0) *= -1.0;  // mirrored: every face now points inward
  for (const SceneMesh& m : BuildScene(model, state).meshes) {
    if (m.layer == MeshLayer::kSoftTissue) {
      EXPECT_FALSE(m.closed) << m.name;
    }
  }
}

}  // namespace
}  // namespace arthrosim::render
