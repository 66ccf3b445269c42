// The look of the views, measured on pixels: automatic exposure (clipped share inside the field
// stop), the tissue-id buffer, each tissue's mean colour in the scope and overview views, and
// the footprint, spur and tear seen from the scope portal on the shoulder scene.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "arthrosim/input/script_source.h"
#include "arthrosim/io/scenario_loader.h"
#include "arthrosim/render/renderer.h"
#include "test_scene.h"

namespace arthrosim::render {
namespace {

using testing::kPi;
using testing::MakeTestScene;
using testing::SharedRenderer;

constexpr double kMaxClippedShare = 0.02;

ViewSpec Spec(View view, int w, int h) {
  ViewSpec s;
  s.view = view;
  s.width = w;
  s.height = h;
  s.overlay = false;
  return s;
}

std::string Source(const std::string& rel) { return std::string(ARTHROSIM_SOURCE_DIR) + "/" + rel; }

struct MeanColour {
  std::array<double, 3> rgb{};
  int pixels = 0;
};

// Mean colour of the pixels showing mesh `mesh` (ids from RenderIds of the same scene and spec).
MeanColour MeanOf(const Image& img, const std::vector<std::int32_t>& ids, int mesh) {
  MeanColour m;
  for (int y = 0; y < img.height; ++y) {
    for (int x = 0; x < img.width; ++x) {
      if (ids[static_cast<std::size_t>(y) * img.width + x] != mesh) continue;
      for (int k = 0; k < 3; ++k) m.rgb[k] += img.At(x, y)[k];
      ++m.pixels;
    }
  }
  if (m.pixels > 0) {
    for (double& c : m.rgb) c /= m.pixels;
  }
  return m;
}

TEST(LookTest, AutoExposureKeepsBrightnessAsTheScopeApproaches) {
  Model model;
  State state = MakeTestScene(&model);
  state.tools[0].instrument = -1;
  const Vec3 target(0, 0, 8);  // the tendon block's top face
  const Vec3 from = state.camera.pose.position_mm - target;
  ViewSpec spec = Spec(View::kScope, 320, 240);
  std::vector<double> luma, luma_fixed;
  double worst_fixed = 0;
  for (const double scale : {0.5, 0.35, 0.25, 0.15}) {  // 16 mm ... 4.8 mm from the surface
    state.camera.pose.position_mm = target + scale * from;
    const Scene scene = BuildScene(model, state);
    Image img;
    std::vector<std::int32_t> ids;
    SharedRenderer().RenderIds(scene, spec, &ids);
    ASSERT_EQ(scene.meshes[0].name, "tendon");
    spec.auto_exposure = true;
    SharedRenderer().Render(scene, spec, &img);
    EXPECT_LT(ClippedShare(img, spec), kMaxClippedShare) << "at scale " << scale;
    const MeanColour m = MeanOf(img, ids, 0);
    ASSERT_GT(m.pixels, 1000);
    luma.push_back(0.2126 * m.rgb[0] + 0.7152 * m.rgb[1] + 0.0722 * m.rgb[2]);
    spec.auto_exposure = false;  // the fixed gain of a camera without auto exposure
    SharedRenderer().Render(scene, spec, &img);
    worst_fixed = std::max(worst_fixed, ClippedShare(img, spec));
    const MeanColour f = MeanOf(img, ids, 0);
    luma_fixed.push_back(0.2126 * f.rgb[0] + 0.7152 * f.rgb[1] + 0.0722 * f.rgb[2]);
    std::printf("scale %.2f tendon luma %.1f (fixed gain %.1f)\n", scale, luma.back(),
                luma_fixed.back());
  }
  // the tendon's brightness held within 50 % over a 3.3x change of distance (11x of irradiance)
  const auto [lo, hi] = std::minmax_element(luma.begin(), luma.end());
  EXPECT_GT(*lo, 110.0);
  EXPECT_LT(*hi / *lo, 1.5);
  // without it, the near views wash out: the checks above are ones the fixed gain fails
  EXPECT_GT(worst_fixed, 0.2);
  EXPECT_GT(luma_fixed.back(), 240.0);
}

TEST(LookTest, RenderIdsNameTheMeshUnderEachPixel) {
  Model model;
  const State state = MakeTestScene(&model);
  const Scene scene = BuildScene(model, state);
  ViewSpec spec = Spec(View::kScope, 160, 120);
  std::vector<std::int32_t> ids;
  SharedRenderer().RenderIds(scene, spec, &ids);
  ASSERT_EQ(ids.size(), 160u * 120u);
  ASSERT_EQ(scene.meshes[0].name, "tendon");
  EXPECT_EQ(ids[60 * 160 + 80], 0);  // the scope looks at the tendon block's top face
  EXPECT_EQ(ids[0], -1);             // outside the field stop
  int outside = 0;
  for (int y = 0; y < 120; ++y) {
    for (int x = 0; x < 160; ++x) {
      const std::int32_t id = ids[static_cast<std::size_t>(y) * 160 + x];
      ASSERT_GE(id, -1);
      ASSERT_LT(id, static_cast<std::int32_t>(scene.meshes.size()));
      if (!InFieldStop(spec, x, y) && std::hypot(x + 0.5 - 80, y + 0.5 - 60) > 58) {
        outside += id != -1;
      }
    }
  }
  EXPECT_EQ(outside, 0);
  // the overview: background -1, the bone sphere (mesh 1) in view
  spec.view = View::kOverview;
  SharedRenderer().RenderIds(scene, spec, &ids);
  EXPECT_EQ(ids[0], -1);
  EXPECT_GT(std::count(ids.begin(), ids.end(), 1), 200);
}

constexpr double kPanelHalfHeight = 20.0;

// One flat panel (12 x 40 mm, subdivided) per tissue in a row, facing +z at z = 0.
Scene TissuePanels(const std::vector<std::pair<std::string, bool>>& tissues) {
  Scene scene;
  const int n = 12;
  for (std::size_t t = 0; t < tissues.size(); ++t) {
    SceneMesh m;
    m.name = tissues[t].first;
    m.layer = tissues[t].second ? MeshLayer::kBone : MeshLayer::kSoftTissue;
    m.material = TissueMaterial(m.name, tissues[t].second);
    const double x0 = -0.5 * 13.0 * static_cast<double>(tissues.size()) + 13.0 * t;
    for (int j = 0; j <= n; ++j) {
      for (int i = 0; i <= n; ++i) {
        Vertex v{};
        v.pos[0] = v.tex[0] = static_cast<float>(x0 + i);
        v.pos[1] = v.tex[1] = static_cast<float>(kPanelHalfHeight * (2.0 * j / n - 1.0));
        v.normal[2] = 1.0f;
        v.uv[0] = 1.0f;  // bone grain factor
        m.vertices.push_back(v);
      }
    }
    for (int j = 0; j < n; ++j) {
      for (int i = 0; i < n; ++i) {
        const auto a = static_cast<std::uint32_t>(j * (n + 1) + i);
        m.indices.insert(m.indices.end(), {a, a + 1, a + n + 2, a, a + n + 2, a + n + 1});
      }
    }
    scene.meshes.push_back(std::move(m));
  }
  scene.bounds_min = Vec3(-0.5 * 13.0 * static_cast<double>(tissues.size()), -kPanelHalfHeight, -1);
  scene.bounds_max = -scene.bounds_min;
  return scene;
}

// Per tissue: the mean colour of its pixels (0..255) must lie in [lo, hi] per channel, and the
// hue relations hold (checked in the test body).
struct ColourRange {
  const char* name;
  bool bone;
  std::array<double, 3> lo, hi;
};

// Ranges for the scope view under auto exposure and the overview's headlight alike.
constexpr ColourRange kTissueRanges[] = {
    {"supraspinatus_muscle", false, {90, 10, 5}, {240, 125, 115}},      // red
    {"humerus", true, {115, 100, 65}, {255, 245, 210}},                 // ivory
    {"supraspinatus_tendon", false, {120, 115, 100}, {255, 255, 245}},  // white
    {"humeral_cartilage", false, {120, 125, 135}, {255, 255, 255}},     // bluish-white
    {"subacromial_bursa", false, {110, 40, 35}, {240, 150, 140}},       // reddish
};

TEST(LookTest, EachTissueMeanColourInItsRange) {
  std::vector<std::pair<std::string, bool>> tissues;
  for (const ColourRange& r : kTissueRanges) tissues.emplace_back(r.name, r.bone);
  Scene scene = TissuePanels(tissues);
  scene.scope.fov_rad = 105 * kPi / 180;
  scene.scope.lens_angle_rad = 30 * kPi / 180;
  scene.scope.far_mm = 200;
  for (const View view : {View::kScope, View::kOverview}) {
    const ViewSpec spec = Spec(view, 320, 240);
    Image img;
    std::vector<std::int32_t> ids;
    std::vector<MeanColour> means;
    for (std::size_t t = 0; t < std::size(kTissueRanges); ++t) {
      const ColourRange& r = kTissueRanges[t];
      // the scope 20 mm from the tissue's panel centre, looking at it obliquely (30 deg lens);
      // the overview frames all panels
      const Vec3 centre(-0.5 * 13.0 * static_cast<double>(tissues.size()) + 13.0 * t + 6, 0, 0);
      scene.scope.pose =
          AimScope(centre + Vec3(0, -8, 18.3), centre, Vec3::UnitY(), 30 * kPi / 180);
      SharedRenderer().Render(scene, spec, &img);
      SharedRenderer().RenderIds(scene, spec, &ids);
      const MeanColour m = MeanOf(img, ids, static_cast<int>(t));
      means.push_back(m);
      ASSERT_GT(m.pixels, 300) << r.name << " in " << ViewName(view);
      for (int k = 0; k < 3; ++k) {
        EXPECT_GE(m.rgb[k], r.lo[k]) << r.name << " channel " << k << " in " << ViewName(view);
        EXPECT_LE(m.rgb[k], r.hi[k]) << r.name << " channel " << k << " in " << ViewName(view);
      }
    }
    const auto& muscle = means[0].rgb;
    const auto& bone = means[1].rgb;
    const auto& tendon = means[2].rgb;
    const auto& cartilage = means[3].rgb;
    const auto& bursa = means[4].rgb;
    EXPECT_LT(tendon[0] - tendon[2], 40) << "tendon white, not yellow";
    EXPECT_GT(muscle[0], 1.7 * muscle[1]) << "muscle red";
    EXPECT_GE(cartilage[2], cartilage[0]) << "cartilage bluish";
    EXPECT_GT(bursa[0], bursa[1] + 40) << "bursa reddish";
    EXPECT_GT(bone[0], bone[2] + 25) << "bone ivory (warm)";
    EXPECT_GT(bone[2], muscle[2] + 40) << "bone far paler than muscle";
  }
}

TEST(LookTest, TexturesVaryWithinATissue) {
  // fibre bundles on tendon and muscle, vessels on the bursa: pixel spread inside one tissue
  Scene scene = TissuePanels(
      {{"supraspinatus_tendon", false}, {"supraspinatus_muscle", false}, {"bursa", false}});
  scene.scope.fov_rad = 105 * kPi / 180;
  scene.scope.far_mm = 200;
  scene.scope.pose = AimScope(Vec3(0, 0, 16), Vec3::Zero(), Vec3::UnitY(), 0);
  const ViewSpec spec = Spec(View::kScope, 320, 240);
  Image img;
  std::vector<std::int32_t> ids;
  SharedRenderer().Render(scene, spec, &img);
  SharedRenderer().RenderIds(scene, spec, &ids);
  for (int t = 0; t < 3; ++t) {
    // spread of the red channel against the 5 x 5 local mean (pattern, not the light fall-off)
    double sum2 = 0;
    int n = 0;
    for (int y = 2; y < img.height - 2; ++y) {
      for (int x = 2; x < img.width - 2; ++x) {
        bool all = true;
        double local = 0;
        for (int dy = -2; dy <= 2 && all; ++dy) {
          for (int dx = -2; dx <= 2; ++dx) {
            all = all && ids[static_cast<std::size_t>(y + dy) * img.width + x + dx] == t;
            local += img.At(x + dx, y + dy)[0];
          }
        }
        if (!all) continue;
        const double d = img.At(x, y)[0] - local / 25;
        sum2 += d * d;
        ++n;
      }
    }
    ASSERT_GT(n, 500) << scene.meshes[t].name;
    EXPECT_GT(std::sqrt(sum2 / n), 1.2) << scene.meshes[t].name << " looks flat";
  }
}

TEST(LookTest, CauteryChars) {
  // marked tendon is dark; burred bone is red (bleeding cancellous bed)
  Scene scene = TissuePanels({{"supraspinatus_tendon", false}, {"humerus", true}});
  scene.scope.fov_rad = 105 * kPi / 180;
  scene.scope.far_mm = 200;
  scene.scope.pose = AimScope(Vec3(0, 0, 22), Vec3::Zero(), Vec3::UnitY(), 0);
  ViewSpec spec = Spec(View::kScope, 320, 240);
  spec.auto_exposure = false;  // compare albedo under the same gain
  std::vector<std::int32_t> ids;
  Image before, after;
  SharedRenderer().Render(scene, spec, &before);
  SharedRenderer().RenderIds(scene, spec, &ids);
  for (SceneMesh& m : scene.meshes) {
    for (Vertex& v : m.vertices) v.rough = 1.0f;
  }
  SharedRenderer().Render(scene, spec, &after);
  const MeanColour t0 = MeanOf(before, ids, 0), t1 = MeanOf(after, ids, 0);
  const MeanColour b0 = MeanOf(before, ids, 1), b1 = MeanOf(after, ids, 1);
  EXPECT_LT(t1.rgb[1], 0.4 * t0.rgb[1]) << "cauterised tendon charred";
  EXPECT_GT(b1.rgb[0] - b1.rgb[2], b0.rgb[0] - b0.rgb[2] + 15) << "burred bone redder";
  EXPECT_LT(b1.rgb[1], 0.8 * b0.rgb[1]) << "burred bone darker (bleeding bed)";
}

// The shoulder scene with the scope at its start pose (posterior portal, subacromial space).
struct Shoulder {
  Model model;
  State state;
  Shoulder() {
    model = io::LoadScenario(Source("scenarios/rotator_cuff_repair.yaml"));
    state = MakeInitialState(model);
  }
  // Position of landmark `name` (mm); NaN if the scenario has none of that name.
  Vec3 LandmarkAt(const std::string& name) const {
    for (const arthrosim::Landmark& l : model.landmarks) {
      if (l.name == name) return l.position_mm;
    }
    return Vec3::Constant(std::nan(""));
  }
};

TEST(LookTest, FootprintSpurAndTearVisibleFromTheScopePortal) {
  const Shoulder s;
  struct Target {
    const char* landmark;
    const char* body;
  };
  const Target targets[] = {{"footprint_center", "humerus"},
                            {"spur_tip", "acromion"},
                            {"tear_edge_center", "supraspinatus_tendon"}};
  const double lens = s.model.camera.lens_angle_deg * kPi / 180;
  for (const Target& t : targets) {
    State state = s.state;
    const Vec3 eye = s.state.camera.pose.position_mm;
    const Vec3 target = s.LandmarkAt(t.landmark);
    ASSERT_TRUE(target.allFinite()) << t.landmark;
    state.camera.pose = AimScope(eye, target, Vec3::UnitZ(), lens);
    state.camera.lens_roll_rad = state.camera.head_roll_rad = 0;
    const Scene scene = BuildScene(s.model, state);
    const ViewSpec spec = Spec(View::kScope, 320, 240);
    std::vector<std::int32_t> ids;
    SharedRenderer().RenderIds(scene, spec, &ids);
    int body = -1;
    for (std::size_t i = 0; i < scene.meshes.size(); ++i) {
      if (scene.meshes[i].name == t.body) body = static_cast<int>(i);
    }
    ASSERT_GE(body, 0) << t.body;
    // the landmark is on the view axis: the centre pixel shows its body, not something in front
    EXPECT_EQ(ids[120 * 320 + 160], body) << t.landmark;
    int inside = 0, shown = 0;
    for (int y = 0; y < 240; ++y) {
      for (int x = 0; x < 320; ++x) {
        if (!InFieldStop(spec, x, y)) continue;
        ++inside;
        shown += ids[static_cast<std::size_t>(y) * 320 + x] == body;
      }
    }
    EXPECT_GT(shown, inside / 20) << t.landmark << ": " << t.body << " covers too little";
    Image img;
    SharedRenderer().Render(scene, spec, &img);
    EXPECT_LT(ClippedShare(img, spec), kMaxClippedShare) << t.landmark;
  }
}

TEST(LookTest, TourFramesStayUnderTheClippedShare) {
  // The tour's scope and instrument poses (trajectories/rotator_cuff_tour.yaml) every 0.5 s on
  // the initial anatomy (the views of the tour without stepping the physics).
  const Shoulder s;
  input::ScriptOptions options;
  const auto script =
      input::ScriptSource::Open(Source("trajectories/rotator_cuff_tour.yaml"), s.model, options);
  ViewSpec spec = Spec(View::kScope, 320, 240);
  double worst = 0, worst_fixed = 0, worst_t = 0;
  int frames = 0;
  for (double t = 0; t <= script->end_time_s(); t += 0.5, ++frames) {
    InputFrame in;
    script->Frame(std::llround(t / 0.02), t, &in);
    State state = s.state;
    state.camera.pose = in.camera.pose;
    state.camera.lens_roll_rad = in.camera.lens_roll_rad;
    state.camera.head_roll_rad = in.camera.head_roll_rad;
    for (int k = 0; k < kToolSlots; ++k) {
      state.tools[k].instrument = in.tools[k].instrument;
      state.tools[k].pose = state.tools[k].handle_pose = in.tools[k].pose;
      state.tools[k].jaw = in.tools[k].jaw;
    }
    const Scene scene = BuildScene(s.model, state);
    Image img;
    spec.auto_exposure = true;
    SharedRenderer().Render(scene, spec, &img);
    const double share = ClippedShare(img, spec);
    EXPECT_LT(share, kMaxClippedShare) << "t = " << t << " s";
    if (share > worst) {
      worst = share;
      worst_t = t;
    }
    spec.auto_exposure = false;
    SharedRenderer().Render(scene, spec, &img);
    worst_fixed = std::max(worst_fixed, ClippedShare(img, spec));
  }
  EXPECT_GT(frames, 60);
  RecordProperty("worst_clipped_share", std::to_string(worst));
  std::printf("tour: %d frames, worst clipped share %.4f at t = %.1f s (fixed gain: %.4f)\n",
              frames, worst, worst_t, worst_fixed);
  // the fixed gain washes frames out: this test fails without the auto exposure
  EXPECT_GT(worst_fixed, kMaxClippedShare);
}

}  // namespace
}  // namespace arthrosim::render
