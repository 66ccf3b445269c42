// The anatomic shoulder's own tissues on rendered frames (scenarios/rotator_cuff_repair_anatomic
// .yaml): the humeral cartilage and the glenoid labrum are meshes of their own (their own ids in
// the tissue-id buffer, their own material), the subacromial bursa is drawn reddish. Each view
// aims the scope from a point in the scene at a point on the tissue; the mean colour of the
// tissue's pixels (tissue-id buffer) must lie in a stated range and differ from bone's.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "arthrosim/io/scenario_loader.h"
#include "arthrosim/mesh/surface_tissue.h"
#include "arthrosim/render/renderer.h"
#include "test_scene.h"

namespace arthrosim::render {
namespace {

using testing::kPi;
using testing::SharedRenderer;

struct Anatomic {
  Model model;
  State state;
  Anatomic() {
    model = io::LoadScenario(std::string(ARTHROSIM_SOURCE_DIR) +
                             "/scenarios/rotator_cuff_repair_anatomic.yaml");
    state = MakeInitialState(model);
  }
  Vec3 Landmark(const std::string& name) const {
    const int i = model.FindLandmark(name);
    return i < 0 ? Vec3::Constant(std::nan("")) : model.landmarks[i].position_mm;
  }
  // Centroid of the triangle of `tissue` on `bone` nearest to `p`.
  Vec3 TissuePointNear(const std::string& bone, const std::string& tissue, const Vec3& p) const {
    const BoneModel& b = model.bones[static_cast<std::size_t>(model.FindBone(bone))];
    double best = 1e300;
    Vec3 at = Vec3::Constant(std::nan(""));
    for (std::size_t t = 0; t < b.surface.tris.size(); ++t) {
      const std::int8_t l = b.tri_tissue.empty() ? mesh::kBoneTissue : b.tri_tissue[t];
      if (l == mesh::kBoneTissue || b.tissues[static_cast<std::size_t>(l)] != tissue) continue;
      const mesh::Tri& tri = b.surface.tris[t];
      const Vec3 c = (b.surface.nodes.col(tri[0]) + b.surface.nodes.col(tri[1]) +
                      b.surface.nodes.col(tri[2])) /
                     3.0;
      if ((c - p).norm() < best) {
        best = (c - p).norm();
        at = c;
      }
    }
    return at;
  }
};

struct View1 {
  std::array<double, 3> rgb{};  // mean colour of the mesh's pixels, 0..255
  int pixels = 0;               // pixels of the mesh inside the image
  bool centre = false;          // the centre pixel shows the mesh
};

// The scope at `eye` aimed at `target`; the pixels of mesh `name`.
View1 Look(const Anatomic& a, const Vec3& eye, const Vec3& target, const std::string& name) {
  State state = a.state;
  state.camera.pose =
      AimScope(eye, target, Vec3::UnitZ(), a.model.camera.lens_angle_deg * kPi / 180);
  state.camera.lens_roll_rad = state.camera.head_roll_rad = 0;
  const Scene scene = BuildScene(a.model, state);
  int mesh = -1;
  for (std::size_t i = 0; i < scene.meshes.size(); ++i)
    if (scene.meshes[i].name == name) mesh = static_cast<int>(i);
  View1 v;
  if (mesh < 0) return v;
  ViewSpec spec;
  spec.view = View::kScope;
  spec.width = 320;
  spec.height = 240;
  spec.overlay = false;
  Image img;
  std::vector<std::int32_t> ids;
  SharedRenderer().Render(scene, spec, &img);
  SharedRenderer().RenderIds(scene, spec, &ids);
  for (int y = 0; y < img.height; ++y) {
    for (int x = 0; x < img.width; ++x) {
      if (ids[static_cast<std::size_t>(y) * img.width + x] != mesh) continue;
      for (int k = 0; k < 3; ++k) v.rgb[k] += img.At(x, y)[k];
      ++v.pixels;
    }
  }
  if (v.pixels > 0)
    for (double& c : v.rgb) c /= v.pixels;
  v.centre = ids[static_cast<std::size_t>(120) * 320 + 160] == mesh;
  return v;
}

void Print(const char* what, const View1& v) {
  std::printf("%-22s %6d px  mean rgb %.1f %.1f %.1f%s\n", what, v.pixels, v.rgb[0], v.rgb[1],
              v.rgb[2], v.centre ? "  (centre pixel)" : "");
}

TEST(AnatomicLook, CartilageLabrumAndBursaAreTheirOwnTissuesWithTheirOwnColours) {
  const Anatomic a;
  // the bone parts and tissue parts are separate meshes of the scene
  {
    const Scene scene = BuildScene(a.model, a.state);
    std::vector<std::string> names;
    for (const SceneMesh& m : scene.meshes) names.push_back(m.name);
    for (const char* n :
         {"humerus", "humerus/cartilage", "glenoid", "glenoid/labrum", "subacromial_bursa"})
      EXPECT_NE(std::find(names.begin(), names.end(), n), names.end()) << n;
  }
  // Cartilage: from the joint space (glenohumeral_view) at the head cartilage nearest to it.
  const Vec3 joint = a.Landmark("glenohumeral_view");
  const View1 cart =
      Look(a, joint, a.TissuePointNear("humerus", "cartilage", joint), "humerus/cartilage");
  // Bone: the footprint (bone of the same humerus) from the scene's scope pose.
  const Vec3 scope = a.model.camera.initial_pose.position_mm;
  const View1 bone = Look(a, scope, a.Landmark("footprint_center"), "humerus");
  // Labrum: from the joint space at the labrum nearest to it.
  const View1 labrum =
      Look(a, joint, a.TissuePointNear("glenoid", "labrum", joint), "glenoid/labrum");
  // Bursa: from the scope pose at its centre.
  const View1 bursa = Look(a, scope, a.Landmark("bursa_center"), "subacromial_bursa");
  Print("humerus/cartilage", cart);
  Print("humerus (footprint)", bone);
  Print("glenoid/labrum", labrum);
  Print("subacromial_bursa", bursa);

  for (const View1* v : {&cart, &bone, &labrum, &bursa}) {
    EXPECT_TRUE(v->centre);
    EXPECT_GT(v->pixels, 2000);  // of 320 x 240
  }
  // cartilage smooth bluish-white: pale (every channel >= 100), blue above red; bone warm
  // (ivory): red above blue; the two hues at least 20 apart in (blue - red)
  for (int k = 0; k < 3; ++k) EXPECT_GE(cart.rgb[k], 100) << "cartilage channel " << k;
  EXPECT_GE(cart.rgb[2] - cart.rgb[0], 5) << "cartilage bluish";
  EXPECT_LE(bone.rgb[2] - bone.rgb[0], -10) << "bone ivory (warm)";
  EXPECT_GT((cart.rgb[2] - cart.rgb[0]) - (bone.rgb[2] - bone.rgb[0]), 20)
      << "cartilage distinct from bone";
  // labrum, fibrocartilage: pale (every channel >= 90), whiter (less yellow) than bone
  for (int k = 0; k < 3; ++k) EXPECT_GE(labrum.rgb[k], 90) << "labrum channel " << k;
  EXPECT_LT(labrum.rgb[0] - labrum.rgb[2], 0.5 * (bone.rgb[0] - bone.rgb[2]))
      << "labrum whiter than bone";
  // bursa reddish
  EXPECT_GT(bursa.rgb[0], bursa.rgb[1] + 40) << "bursa reddish";
  EXPECT_GT(bursa.rgb[0], bursa.rgb[2] + 40) << "bursa reddish";
  EXPECT_GE(bursa.rgb[0], 90) << "bursa red channel";
}

}  // namespace
}  // namespace arthrosim::render
