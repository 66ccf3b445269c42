#include "arthrosim/render/scene.h"

#include <gtest/gtest.h>

#include <map>

#include "test_scene.h"

namespace arthrosim::render {
namespace {

using testing::kPi;
using testing::MakeTestScene;

constexpr double kTol = 1e-9;

const SceneMesh* Find(const Scene& s, const std::string& name, MeshLayer layer) {
  for (const SceneMesh& m : s.meshes) {
    if (m.name == name && m.layer == layer) return &m;
  }
  return nullptr;
}

Vec3 P(const Vertex& v) { return Vec3(v.pos[0], v.pos[1], v.pos[2]); }
Vec3 N(const Vertex& v) { return Vec3(v.normal[0], v.normal[1], v.normal[2]); }

bool Closed(const SceneMesh& m) {
  std::map<std::pair<std::uint32_t, std::uint32_t>, int> directed;
  for (std::size_t t = 0; t < m.indices.size(); t += 3) {
    for (int k = 0; k < 3; ++k) ++directed[{m.indices[t + k], m.indices[t + (k + 1) % 3]}];
  }
  // each directed edge matched by as many reversed ones (closed, consistently oriented)
  for (const auto& [e, c] : directed) {
    auto it = directed.find({e.second, e.first});
    if (it == directed.end() || it->second != c) return false;
  }
  return true;
}

TEST(ScopeViewFrameTest, ObliqueLensAndRolls) {
  SceneScope s;
  s.lens_angle_rad = 30 * kPi / 180;
  ViewFrame f = ScopeViewFrame(s);
  EXPECT_NEAR((f.forward - Vec3(0, 0.5, std::sqrt(3.0) / 2)).norm(), 0, kTol);
  EXPECT_NEAR(f.up.dot(f.forward), 0, kTol);
  EXPECT_GT(f.up.y(), 0.8);
  // light post turned half a turn: the view sweeps to the other side of the shaft
  s.lens_roll_rad = kPi;
  f = ScopeViewFrame(s);
  EXPECT_NEAR((f.forward - Vec3(0, -0.5, std::sqrt(3.0) / 2)).norm(), 0, kTol);
  EXPECT_GT(f.up.y(), 0.8);  // the camera head did not turn: image up unchanged
  // camera head turned +90 deg about +z: up goes from +y to -x
  s.lens_roll_rad = 0;
  s.head_roll_rad = kPi / 2;
  f = ScopeViewFrame(s);
  EXPECT_NEAR((f.up - Vec3(-1, 0, 0)).norm(), 0, kTol);
  // the pose rotates everything
  s.pose.orientation = Quat(Eigen::AngleAxisd(kPi / 2, Vec3::UnitX()));
  s.head_roll_rad = 0;
  f = ScopeViewFrame(s);
  EXPECT_NEAR((f.forward - Vec3(0, -std::sqrt(3.0) / 2, 0.5)).norm(), 0, kTol);
}

TEST(ScopeViewFrameTest, AimScopeLooksAtTarget) {
  const Vec3 eye(3, -20, 15), target(1, 2, 3);
  SceneScope s;
  s.lens_angle_rad = 30 * kPi / 180;
  s.pose = AimScope(eye, target, Vec3::UnitZ(), s.lens_angle_rad);
  const ViewFrame f = ScopeViewFrame(s);
  EXPECT_NEAR((f.forward - (target - eye).normalized()).norm(), 0, kTol);
  EXPECT_GT(f.up.z(), 0.5);
  // the shaft (+z of the tip frame) is 30 deg off the view direction
  const Vec3 shaft = s.pose.orientation * Vec3::UnitZ();
  EXPECT_NEAR(std::acos(shaft.dot(f.forward)), s.lens_angle_rad, 1e-9);
}

TEST(BuildSceneTest, HasEveryBodyWithOutwardUnitNormals) {
  Model model;
  const State state = MakeTestScene(&model);
  const Scene scene = BuildScene(model, state);
  const SceneMesh* tendon = Find(scene, "tendon", MeshLayer::kSoftTissue);
  const SceneMesh* bone = Find(scene, "humerus", MeshLayer::kBone);
  const SceneMesh* thread = Find(scene, "suture", MeshLayer::kThread);
  const SceneMesh* grasper = Find(scene, "grasper", MeshLayer::kInstrument);
  const SceneMesh* scope = Find(scene, "scope", MeshLayer::kScope);
  ASSERT_TRUE(tendon && bone && thread && grasper && scope);
  EXPECT_EQ(Find(scene, "burr", MeshLayer::kInstrument), nullptr);  // not inserted
  EXPECT_FALSE(scope->visible_in_scope);

  EXPECT_EQ(tendon->indices.size(), 3u * 12);
  EXPECT_EQ(tendon->vertices.size(), 8u);
  EXPECT_TRUE(Closed(*tendon));
  EXPECT_TRUE(Closed(*bone));
  const Vec3 centre(0, 0, -12);
  for (const Vertex& v : bone->vertices) {
    EXPECT_NEAR(N(v).norm(), 1.0, 1e-6);
    EXPECT_GT(N(v).dot((P(v) - centre).normalized()), 0.95);
    EXPECT_EQ(v.rough, 0.0f);
  }
  // cube corner normals point away from the cube centre
  for (const Vertex& v : tendon->vertices) {
    EXPECT_GT(N(v).dot(P(v) - Vec3(0, 0, 4)), 0);
  }
  // thread tube: radius 0.275 mm around the chain
  for (const Vertex& v : thread->vertices) {
    double best = 1e9;
    for (Eigen::Index i = 0; i < model.threads[0].initial.nodes.cols(); ++i) {
      best = std::min(best, (P(v) - model.threads[0].initial.nodes.col(i)).norm());
    }
    EXPECT_NEAR(best, 0.275, 1e-5);
  }
  EXPECT_EQ(scene.overlay.tools.size(), 1u);
  EXPECT_EQ(scene.overlay.tools[0].instrument, "grasper");
  EXPECT_NEAR(scene.overlay.tools[0].force_n, 5.0, 1e-12);
  EXPECT_DOUBLE_EQ(scene.overlay.time_s, 1.25);
  // overview frames the bone
  EXPECT_NEAR(scene.bounds_min.z(), -24, 1e-5);
  EXPECT_NEAR(scene.bounds_max.z(), 0, 1e-5);
}

TEST(BuildSceneTest, CutTetsShowTheCutSurface) {
  Model model;
  State state = MakeTestScene(&model);
  state.soft_bodies[0].tet_alive[4] = 0;  // central tet cut away
  const Scene scene = BuildScene(model, state);
  const SceneMesh* tendon = Find(scene, "tendon", MeshLayer::kSoftTissue);
  ASSERT_TRUE(tendon);
  // the 4 faces of the removed tet now bound the 4 corner tets: 12 + 4 triangles, closed,
  // enclosing the cube minus the central third
  EXPECT_EQ(tendon->indices.size(), 3u * 16);
  EXPECT_TRUE(Closed(*tendon));
  double volume = 0;
  for (std::size_t t = 0; t < tendon->indices.size(); t += 3) {
    const Vec3 a = P(tendon->vertices[tendon->indices[t]]),
               b = P(tendon->vertices[tendon->indices[t + 1]]),
               c = P(tendon->vertices[tendon->indices[t + 2]]);
    volume += a.dot(b.cross(c)) / 6.0;
  }
  EXPECT_NEAR(volume, 512.0 * 2.0 / 3.0, 1e-3);
}

TEST(BuildSceneTest, BurredBoneVerticesAreRough) {
  Model model;
  State state = MakeTestScene(&model);
  // push the north pole 0.25 mm in (half the full-roughness depth) and one vertex 2 mm
  state.bones[0].surface.nodes.col(0) += Vec3(0, 0, -0.25);
  const Vec3 p5 = state.bones[0].surface.nodes.col(5);
  state.bones[0].surface.nodes.col(5) += 2.0 * (Vec3(0, 0, -12) - p5).normalized();
  const Scene scene = BuildScene(model, state);
  const SceneMesh* bone = Find(scene, "humerus", MeshLayer::kBone);
  ASSERT_TRUE(bone);
  int rough = 0;
  for (const Vertex& v : bone->vertices) {
    if (v.rough > 0) {
      ++rough;
      if (std::abs(v.pos[2] - (-0.25f)) < 1e-4f && std::abs(v.pos[0]) < 1e-4f) {
        EXPECT_NEAR(v.rough, 0.5f, 1e-5f);
      } else {
        EXPECT_EQ(v.rough, 1.0f);
      }
    }
  }
  EXPECT_EQ(rough, 2);
}

// BuildScene memoises soft-body topology and bone meshes across calls; every frame must still
// equal what the State alone gives, whatever was built before.
bool SameMeshes(const Scene& a, const Scene& b) {
  if (a.meshes.size() != b.meshes.size()) return false;
  for (std::size_t i = 0; i < a.meshes.size(); ++i) {
    const SceneMesh &x = a.meshes[i], &y = b.meshes[i];
    if (x.name != y.name || x.indices != y.indices || x.vertices.size() != y.vertices.size()) {
      return false;
    }
    for (std::size_t v = 0; v < x.vertices.size(); ++v) {
      const Vertex &p = x.vertices[v], &q = y.vertices[v];
      for (int k = 0; k < 3; ++k) {
        if (p.pos[k] != q.pos[k] || p.normal[k] != q.normal[k]) return false;
      }
      if (p.uv[0] != q.uv[0] || p.uv[1] != q.uv[1] || p.rough != q.rough) return false;
    }
  }
  return true;
}

TEST(BuildSceneTest, MemoisedSurfacesFollowTheState) {
  Model model;
  const State intact = MakeTestScene(&model);
  State cut = intact;
  cut.soft_bodies[0].tet_alive[4] = 0;
  State moved = intact;
  moved.soft_bodies[0].x.col(0) += Vec3(0.5, -0.25, 1.0);
  State burred = intact;
  burred.bones[0].surface.nodes.col(0) += Vec3(0, 0, -0.25);

  const Scene first_intact = BuildScene(model, intact);
  const Scene first_cut = BuildScene(model, cut);
  const Scene first_moved = BuildScene(model, moved);
  const Scene first_burred = BuildScene(model, burred);
  EXPECT_FALSE(SameMeshes(first_intact, first_cut));
  EXPECT_FALSE(SameMeshes(first_intact, first_moved));
  EXPECT_FALSE(SameMeshes(first_intact, first_burred));
  // interleaved repeats return exactly the first results
  for (int round = 0; round < 2; ++round) {
    EXPECT_TRUE(SameMeshes(BuildScene(model, cut), first_cut));
    EXPECT_TRUE(SameMeshes(BuildScene(model, intact), first_intact));
    EXPECT_TRUE(SameMeshes(BuildScene(model, burred), first_burred));
    EXPECT_TRUE(SameMeshes(BuildScene(model, moved), first_moved));
  }
  // a moved node changes positions and normals of the cached topology
  const SceneMesh* a = Find(first_intact, "tendon", MeshLayer::kSoftTissue);
  const SceneMesh* b = Find(first_moved, "tendon", MeshLayer::kSoftTissue);
  ASSERT_TRUE(a && b);
  EXPECT_EQ(a->indices, b->indices);
}

TEST(BuildSceneTest, SoftBodyNodeOutOfRangeIsRejected) {
  Model model;
  State state = MakeTestScene(&model);
  state.soft_bodies[0].tets[0][0] = static_cast<std::int32_t>(state.soft_bodies[0].x.cols());
  EXPECT_THROW(BuildScene(model, state), std::invalid_argument);
  state.soft_bodies[0].tets[0][0] = -3;
  EXPECT_THROW(BuildScene(model, state), std::invalid_argument);
}

TEST(BuildSceneTest, JawOpensInTheXZPlane) {
  Model model;
  State state = MakeTestScene(&model);
  state.tools[0].pose = Pose{};  // tool frame = world
  auto x_extent_near_tip = [&](double jaw) {
    state.tools[0].jaw = jaw;
    const Scene scene = BuildScene(model, state);
    const SceneMesh* g = Find(scene, "grasper", MeshLayer::kInstrument);
    double lo = 1e9, hi = -1e9, ylo = 1e9, yhi = -1e9;
    for (const Vertex& v : g->vertices) {
      if (v.pos[2] > -1.0f) {
        lo = std::min(lo, double(v.pos[0]));
        hi = std::max(hi, double(v.pos[0]));
        ylo = std::min(ylo, double(v.pos[1]));
        yhi = std::max(yhi, double(v.pos[1]));
      }
    }
    return std::make_pair(hi - lo, yhi - ylo);
  };
  const auto open = x_extent_near_tip(0.0), closed = x_extent_near_tip(1.0);
  // fully open: each 8 mm jaw is 25 deg off axis, so the tips are ~2 * 8 sin 25 = 6.8 mm apart
  EXPECT_GT(open.first, 6.0);
  EXPECT_LT(closed.first, 4.0);                   // two 1.8 mm jaws side by side, tapering
  EXPECT_NEAR(open.second, closed.second, 1e-5);  // nothing moves along y
}

TEST(BuildSceneTest, EveryInstrumentKindHasAShape) {
  Model model;
  State state = MakeTestScene(&model);
  state.tools[0].jaw = 1.0;  // closed: the jaw tips meet at the tool tip
  for (int k = 0; k < kInstrumentKindCount; ++k) {
    model.instruments[0].kind = static_cast<InstrumentKind>(k);
    const Scene scene = BuildScene(model, state);
    const SceneMesh* g = Find(scene, "grasper", MeshLayer::kInstrument);
    ASSERT_TRUE(g) << k;
    EXPECT_GT(g->indices.size(), 3u * 40) << k;
    // the shape reaches the tip (origin of the tool frame) but not far beyond it
    double best = 1e9, farthest = 0;
    const Vec3 tip = state.tools[0].pose.position_mm;
    const Vec3 fwd = state.tools[0].pose.orientation * Vec3::UnitZ();
    for (const Vertex& v : g->vertices) {
      best = std::min(best, (P(v) - tip).norm());
      farthest = std::max(farthest, (P(v) - tip).dot(fwd));
    }
    EXPECT_LT(best, 2.6) << k;
    EXPECT_LT(farthest, 3.1) << k;
  }
}

TEST(BuildSceneTest, MismatchedStateIsRejected) {
  Model model;
  State state = MakeTestScene(&model);
  state.bones.clear();
  EXPECT_THROW(BuildScene(model, state), std::invalid_argument);
  state = MakeTestScene(&model);
  state.tools[1].instrument = 7;
  EXPECT_THROW(BuildScene(model, state), std::invalid_argument);
  state = MakeTestScene(&model);
  state.soft_bodies[0].tets[0][0] = 99;
  EXPECT_THROW(BuildScene(model, state), std::invalid_argument);
}

TEST(TissueMaterialTest, ColoursByName) {
  const SceneMaterial muscle = TissueMaterial("supraspinatus_muscle", false);
  const SceneMaterial tendon = TissueMaterial("supraspinatus_tendon", false);
  const SceneMaterial bone = TissueMaterial("humerus", true);
  EXPECT_GT(muscle.base_color[0], muscle.base_color[1] + 0.25f);  // red-brown
  EXPECT_GT(tendon.base_color[1], 0.8f);                          // white-yellow
  EXPECT_GT(tendon.specular, bone.specular);                      // wet and glossy
  EXPECT_EQ(bone.pattern, 2);
}

}  // namespace
}  // namespace arthrosim::render
