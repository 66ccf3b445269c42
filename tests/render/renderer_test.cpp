#include "arthrosim/render/renderer.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>

#include "test_scene.h"

namespace arthrosim::render {
namespace {

using testing::kPi;
using testing::MakeTestScene;
using testing::SharedRenderer;
using testing::ToolPose;

// Golden images differ from a fresh render only by rasteriser rounding (other CPUs / LLVM
// builds); a moved object or changed colour drops PSNR far below this.
constexpr double kGoldenMinPsnrDb = 40.0;

// Distance of pixel (x, y) (top-down) from the centre of a w x h viewport, in pixels.
double CentreDistance(int x, int y, int w, int h, double* dx = nullptr, double* dy_up = nullptr) {
  const double ddx = x + 0.5 - 0.5 * w, ddy = (h - y - 0.5) - 0.5 * h;
  if (dx) *dx = ddx;
  if (dy_up) *dy_up = ddy;
  return std::hypot(ddx, ddy);
}

ViewSpec Spec(View view, int w, int h) {
  ViewSpec s;
  s.view = view;
  s.width = w;
  s.height = h;
  return s;
}

TEST(RendererTest, ContextIsLlvmpipe) {
  EXPECT_NE(SharedRenderer().GlRenderer().find("llvmpipe"), std::string::npos)
      << SharedRenderer().GlRenderer();
}

TEST(RendererTest, BlackOutsideFieldStopLitInside) {
  Model model;
  const State state = MakeTestScene(&model);
  ViewSpec spec = Spec(View::kScope, 320, 240);
  spec.overlay = false;
  Image img;
  SharedRenderer().Render(BuildScene(model, state), spec, &img);
  ASSERT_EQ(img.width, 320);
  ASSERT_EQ(img.height, 240);
  const double radius = 0.5 * spec.field_stop * 240;
  int dark_inside = 0;
  for (int y = 0; y < img.height; ++y) {
    for (int x = 0; x < img.width; ++x) {
      const std::uint8_t* p = img.At(x, y);
      const double d = CentreDistance(x, y, img.width, img.height);
      if (d > radius + 1.0) {
        ASSERT_EQ(p[0] | p[1] | p[2], 0) << "pixel " << x << "," << y << " outside the stop";
      } else if (d < radius - 1.0 && p[0] == 0) {
        ++dark_inside;  // the fluid itself is dim but never black
      }
    }
  }
  EXPECT_EQ(dark_inside, 0);
  // the scope looks at the tendon block's top face: lit, and dimmer from twice as far
  // (inverse-square fall-off of the light at the lens)
  auto centre_luma = [](const Image& im) {
    double sum = 0;
    for (int y = im.height / 2 - 3; y < im.height / 2 + 3; ++y) {
      for (int x = im.width / 2 - 3; x < im.width / 2 + 3; ++x) {
        sum += (im.At(x, y)[0] + im.At(x, y)[1] + im.At(x, y)[2]) / 3.0;
      }
    }
    return sum / 36;
  };
  EXPECT_GT(centre_luma(img), 100.0);
  // under a fixed gain (auto exposure off)
  spec.auto_exposure = false;
  SharedRenderer().Render(BuildScene(model, state), spec, &img);
  const double near = centre_luma(img);
  EXPECT_GT(near, 100.0);
  State far = state;
  const Vec3 target(0, 0, 8);
  far.camera.pose.position_mm = target + 2.0 * (state.camera.pose.position_mm - target);
  SharedRenderer().Render(BuildScene(model, far), spec, &img);
  EXPECT_LT(centre_luma(img), 0.6 * near);
}

// Scope at the origin, nothing but a burr whose tip point lies 15 mm along `dir`, pointing back
// at the scope: its sphere (radius 3), whose front is the tip point, is centred 18 mm away and
// its shaft points away behind it. Returns the pixels that differ from the empty view.
struct Coverage {
  int count = 0;
  double cx = 0, cy_up = 0;  // centroid relative to the image centre, pixels (y up)
  std::vector<std::uint8_t> mask;
};

Coverage BurrCoverage(const Vec3& dir_local, double lens_roll, double head_roll, int w, int h,
                      double* radius_px, double distance = 15.0) {
  Model model;
  State state = MakeTestScene(&model);
  model.soft_bodies.clear();
  model.bones.clear();
  model.threads.clear();
  state.soft_bodies.clear();
  state.bones.clear();
  state.threads.clear();
  state.tools[0].instrument = -1;
  state.camera.pose = Pose{};
  state.camera.lens_roll_rad = lens_roll;
  state.camera.head_roll_rad = head_roll;
  ViewSpec spec = Spec(View::kScope, w, h);
  spec.overlay = false;
  spec.distortion = 0.0;       // rectilinear: the silhouette of a sphere has an analytic size
  spec.auto_exposure = false;  // the same gain with and without the burr
  *radius_px = 0.5 * spec.field_stop * std::min(w, h);
  Image empty, with;
  SharedRenderer().Render(BuildScene(model, state), spec, &empty);
  const Vec3 d = dir_local.normalized();
  state.tools[1].instrument = 1;  // burr
  state.tools[1].pose = ToolPose(distance * d, -d);
  SharedRenderer().Render(BuildScene(model, state), spec, &with);
  Coverage c;
  c.mask.assign(static_cast<std::size_t>(w) * h, 0);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const std::uint8_t *a = empty.At(x, y), *b = with.At(x, y);
      const int diff = std::abs(a[0] - b[0]) + std::abs(a[1] - b[1]) + std::abs(a[2] - b[2]);
      double dx, dy;
      CentreDistance(x, y, w, h, &dx, &dy);
      if (diff > 24) {
        c.mask[static_cast<std::size_t>(y) * w + x] = 1;
        ++c.count;
        c.cx += dx;
        c.cy_up += dy;
      }
    }
  }
  if (c.count > 0) {
    c.cx /= c.count;
    c.cy_up /= c.count;
  }
  return c;
}

TEST(RendererTest, InstrumentOnViewAxisCoversTheExpectedDisc) {
  const int w = 320, h = 240;
  double radius;
  const double half = 105.0 / 2 * kPi / 180;
  const Vec3 view(0, std::sin(kPi / 6), std::cos(kPi / 6));
  const Coverage c = BurrCoverage(view, 0, 0, w, h, &radius);
  // silhouette cone half-angle asin(3 / 18); rectilinear image radius tan(alpha) / tan(half)
  const double alpha = std::asin(3.0 / 18.0);
  const double expect_px = radius * std::tan(alpha) / std::tan(half);
  ASSERT_GT(c.count, 0);
  EXPECT_NEAR(c.cx, 0, 0.5);
  EXPECT_NEAR(c.cy_up, 0, 0.5);
  EXPECT_NEAR(c.count, kPi * expect_px * expect_px, 0.08 * kPi * expect_px * expect_px);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const double r = CentreDistance(x, y, w, h);
      const bool covered = c.mask[static_cast<std::size_t>(y) * w + x] != 0;
      if (r < expect_px - 1.5) {
        EXPECT_TRUE(covered) << x << "," << y;
      }
      if (r > expect_px + 1.5) {
        EXPECT_FALSE(covered) << x << "," << y;
      }
    }
  }
}

TEST(RendererTest, ObliqueLensShowsTheShaftAxisBelowCentre) {
  const int w = 320, h = 240;
  double radius;
  const double half = 105.0 / 2 * kPi / 180;
  // the shaft axis is 30 deg from the view direction, toward image-down at zero rolls
  Coverage c = BurrCoverage(Vec3::UnitZ(), 0, 0, w, h, &radius);
  const double expect = radius * std::tan(kPi / 6) / std::tan(half);
  ASSERT_GT(c.count, 100);
  EXPECT_NEAR(c.cx, 0, 1.0);
  EXPECT_NEAR(c.cy_up, -expect, 3.0);  // perspective stretches the disc outward a little
  // camera head +90 deg about the shaft: the image turns, the axis is now to the right
  c = BurrCoverage(Vec3::UnitZ(), 0, kPi / 2, w, h, &radius);
  EXPECT_NEAR(c.cx, expect, 3.0);
  EXPECT_NEAR(c.cy_up, 0, 1.0);
  // light post half a turn: the view swings to the other side, the axis is above centre
  c = BurrCoverage(Vec3::UnitZ(), kPi, 0, w, h, &radius);
  EXPECT_NEAR(c.cx, 0, 1.0);
  EXPECT_NEAR(c.cy_up, expect, 3.0);
  // centred at 33 mm the sphere spans +-5.2 deg: 60 deg off the view direction it is just outside
  // the 105 deg field, 45 deg off it is inside
  c = BurrCoverage(Vec3(0, -std::sin(kPi / 6), std::cos(kPi / 6)), 0, 0, w, h, &radius, 30.0);
  EXPECT_EQ(c.count, 0);
  c = BurrCoverage(Vec3(0, std::sin(kPi / 12), std::cos(kPi / 12)), kPi / 2, 0, w, h, &radius,
                   30.0);
  EXPECT_GT(c.count, 50);
}

TEST(RendererTest, IdenticalInputGivesIdenticalPixels) {
  Model model;
  const State state = MakeTestScene(&model);
  const Scene scene = BuildScene(model, state);
  for (View view : {View::kScope, View::kOverview, View::kBoth}) {
    Image a, b, c;
    SharedRenderer().Render(scene, Spec(view, 200, 150), &a);
    SharedRenderer().Render(BuildScene(model, state), Spec(view, 200, 150), &b);
    EXPECT_EQ(a.rgb, b.rgb) << ViewName(view);
    Renderer second;
    second.Render(scene, Spec(view, 200, 150), &c);
    EXPECT_EQ(a.rgb, c.rgb) << ViewName(view);
  }
}

TEST(RendererTest, OverlayDrawsTextInTheCornersOnly) {
  Model model;
  const State state = MakeTestScene(&model);
  Scene scene = BuildScene(model, state);
  scene.overlay.plan_step = "Step 3: pass suture";
  scene.overlay.verdict = "OK";
  ViewSpec spec = Spec(View::kScope, 320, 240);
  Image with, without;
  SharedRenderer().Render(scene, spec, &with);
  spec.overlay = false;
  SharedRenderer().Render(scene, spec, &without);
  auto changed = [&](int x0, int y0, int x1, int y1) {
    int n = 0;
    for (int y = y0; y < y1; ++y) {
      for (int x = x0; x < x1; ++x) n += std::memcmp(with.At(x, y), without.At(x, y), 3) != 0;
    }
    return n;
  };
  EXPECT_GT(changed(0, 0, 80, 20), 20);      // time
  EXPECT_GT(changed(240, 0, 320, 20), 20);   // plan step
  EXPECT_GT(changed(0, 220, 120, 240), 20);  // force bar
  EXPECT_EQ(changed(110, 70, 210, 170), 0);  // the operative field stays clear
}

TEST(RendererTest, MissingFontNamesThePackage) {
  try {
    Renderer r("/nonexistent/DejaVuSans.ttf");
    FAIL() << "no error";
  } catch (const RenderError& e) {
    EXPECT_NE(std::string(e.what()).find("fonts-dejavu-core"), std::string::npos) << e.what();
  }
}

TEST(RendererTest, BadSpecIsRejected) {
  Model model;
  const Scene scene = BuildScene(model, MakeTestScene(&model));
  Image img;
  ViewSpec spec = Spec(View::kScope, 8, 8);
  EXPECT_THROW(SharedRenderer().Render(scene, spec, &img), std::invalid_argument);
  spec = Spec(View::kScope, 64, 64);
  spec.field_stop = 0;
  EXPECT_THROW(SharedRenderer().Render(scene, spec, &img), std::invalid_argument);
  EXPECT_THROW(ParseView("side"), std::invalid_argument);
  EXPECT_EQ(ParseView("both"), View::kBoth);
}

// Goldens: golden/render/<view>_160x120.png. Regenerate after an intended visual change with
//   ARTHROSIM_UPDATE_GOLDEN=1 ./build/tests/render/render_test --gtest_filter='*Golden*'
// and review the PNGs before committing.
class GoldenTest : public ::testing::TestWithParam<View> {};

TEST_P(GoldenTest, MatchesGoldenImage) {
  Model model;
  State state = MakeTestScene(&model);
  state.bones[0].surface.nodes.col(0) += Vec3(0, 0, -0.4);  // a burred spot
  Scene scene = BuildScene(model, state);
  scene.overlay.plan_step = "Step 2";
  const ViewSpec spec = Spec(GetParam(), 160, 120);
  Image img;
  SharedRenderer().Render(scene, spec, &img);
  const std::string path =
      std::string(ARTHROSIM_SOURCE_DIR) + "/golden/render/" + ViewName(GetParam()) + "_160x120.png";
  const char* update = std::getenv("ARTHROSIM_UPDATE_GOLDEN");
  if (update != nullptr && std::string(update) == "1") {
    WritePng(path, img);
    GTEST_SKIP() << "wrote " << path;
  }
  ASSERT_TRUE(std::filesystem::exists(path)) << path << " missing: see the comment above";
  const Image golden = ReadPng(path);
  const double psnr = Psnr(img, golden);
  EXPECT_GT(psnr, kGoldenMinPsnrDb) << path;
  // the threshold is meaningful: moving the scope by 1 mm must fail it
  state.camera.pose.position_mm += Vec3(1, 0, 0);
  Scene moved = BuildScene(model, state);
  moved.overlay.plan_step = "Step 2";
  SharedRenderer().Render(moved, spec, &img);
  if (GetParam() != View::kOverview) {
    EXPECT_LT(Psnr(img, golden), kGoldenMinPsnrDb);
  }
}

INSTANTIATE_TEST_SUITE_P(Views, GoldenTest,
                         ::testing::Values(View::kScope, View::kOverview, View::kBoth),
                         [](const auto& info) { return std::string(ViewName(info.param)); });

}  // namespace
}  // namespace arthrosim::render
