#include "arthrosim/render/video_sink.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include "arthrosim/render/renderer.h"
#include "test_scene.h"

namespace arthrosim::render {
namespace {

namespace fs = std::filesystem;

fs::path TempDir(const std::string& name) {
  const fs::path dir = fs::path(ARTHROSIM_BINARY_DIR) / "tests_tmp" / "render" / name;
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

// Frames with a moving bright square (so the encoder has real content).
Image Frame(int w, int h, int k) {
  Image img;
  img.Resize(w, h);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      std::uint8_t* p = img.At(x, y);
      p[0] = static_cast<std::uint8_t>(x * 255 / w);
      p[1] = static_cast<std::uint8_t>(y * 255 / h);
      p[2] = (x / 8 + y / 8 + k) % 2 ? 200 : 40;
    }
  }
  return img;
}

std::string Run(const std::string& cmd) {
  std::string out;
  FILE* f = popen(cmd.c_str(), "r");
  if (!f) return out;
  char buf[512];
  while (fgets(buf, sizeof buf, f)) out += buf;
  pclose(f);
  return out;
}

std::map<std::string, std::string> Probe(const fs::path& file) {
  const std::string text =
      Run("ffprobe -v error -select_streams v:0 -count_frames -show_entries "
          "stream=codec_name,width,height,nb_read_frames,duration,pix_fmt -of default=nw=1 '" +
          file.string() + "'");
  std::map<std::string, std::string> kv;
  std::stringstream ss(text);
  std::string line;
  while (std::getline(ss, line)) {
    const auto eq = line.find('=');
    if (eq != std::string::npos) kv[line.substr(0, eq)] = line.substr(eq + 1);
  }
  return kv;
}

std::string Bytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

TEST(FfmpegSinkTest, EncodedClipHasFrameCountSizeAndDuration) {
  if (FindProgram("ffmpeg").empty() || FindProgram("ffprobe").empty()) {
    GTEST_SKIP() << "ffmpeg/ffprobe not installed (Debian package ffmpeg)";
  }
  const fs::path dir = TempDir("clip");
  const fs::path out = dir / "clip.mp4";
  {
    FfmpegSink sink(out.string(), 160, 120, 10.0);
    for (int k = 0; k < 12; ++k) sink.Write(Frame(160, 120, k));
    sink.Close();
    EXPECT_EQ(sink.frames(), 12);
  }
  const auto kv = Probe(out);
  EXPECT_EQ(kv.at("codec_name"), "h264");
  EXPECT_EQ(kv.at("width"), "160");
  EXPECT_EQ(kv.at("height"), "120");
  EXPECT_EQ(kv.at("pix_fmt"), "yuv420p");
  EXPECT_EQ(kv.at("nb_read_frames"), "12");
  EXPECT_NEAR(std::stod(kv.at("duration")), 1.2, 1e-3);
  EXPECT_FALSE(fs::exists(out.string() + ".ffmpeg.log"));  // removed on success
}

TEST(FfmpegSinkTest, SameFramesGiveSameBytes) {
  if (FindProgram("ffmpeg").empty()) GTEST_SKIP() << "ffmpeg not installed";
  const fs::path dir = TempDir("bitexact");
  for (const char* name : {"a.mp4", "b.mp4"}) {
    FfmpegSink sink((dir / name).string(), 64, 48, 25.0);
    for (int k = 0; k < 5; ++k) sink.Write(Frame(64, 48, k));
    sink.Close();
  }
  const std::string a = Bytes(dir / "a.mp4"), b = Bytes(dir / "b.mp4");
  EXPECT_GT(a.size(), 100u);
  EXPECT_EQ(a, b);
}

TEST(FfmpegSinkTest, MissingProgramNamesThePackage) {
  FfmpegOptions opt;
  opt.program = "arthrosim-no-such-ffmpeg";
  try {
    FfmpegSink sink("/tmp/never.mp4", 64, 48, 25.0, opt);
    FAIL() << "no error";
  } catch (const RenderError& e) {
    EXPECT_NE(std::string(e.what()).find("Debian package ffmpeg"), std::string::npos) << e.what();
  }
}

TEST(FfmpegSinkTest, BadArgumentsAreRejected) {
  EXPECT_THROW(FfmpegSink("/tmp/x.mp4", 63, 48, 25.0), std::invalid_argument);
  EXPECT_THROW(FfmpegSink("/tmp/x.mp4", 64, 48, 0.0), std::invalid_argument);
}

TEST(FfmpegSinkTest, MissingOutputDirectoryIsReported) {
  if (FindProgram("ffmpeg").empty()) GTEST_SKIP() << "ffmpeg not installed";
  EXPECT_THROW(FfmpegSink("/nonexistent-dir/x.mp4", 64, 48, 25.0), RenderError);
}

TEST(FfmpegSinkTest, EncoderFailureIsReported) {
  if (FindProgram("ffmpeg").empty()) GTEST_SKIP() << "ffmpeg not installed";
  // x264 rejects the preset: ffmpeg exits, writes fail with EPIPE (not SIGPIPE) or Close reports
  FfmpegOptions opt;
  opt.preset = "no-such-preset";
  FfmpegSink sink((TempDir("fail") / "x.mp4").string(), 64, 48, 25.0, opt);
  EXPECT_THROW(
      {
        for (int k = 0; k < 200; ++k) sink.Write(Frame(64, 48, k));
        sink.Close();
      },
      RenderError);
}

TEST(PngDirSinkTest, WritesNumberedFramesThatReadBack) {
  const fs::path dir = TempDir("png");
  PngDirSink sink((dir / "frames").string());
  for (int k = 0; k < 3; ++k) sink.Write(Frame(40, 30, k));
  EXPECT_EQ(sink.frames(), 3);
  for (int k = 0; k < 3; ++k) {
    char name[32];
    std::snprintf(name, sizeof name, "frame_%06d.png", k);
    const Image back = ReadPng((dir / "frames" / name).string());
    EXPECT_EQ(back.rgb, Frame(40, 30, k).rgb);
  }
}

TEST(RendererVideoTest, RenderedFramesEncode) {
  if (FindProgram("ffmpeg").empty()) GTEST_SKIP() << "ffmpeg not installed";
  testing::PinLlvmpipeThreads();
  Model model;
  State state = testing::MakeTestScene(&model);
  Renderer renderer;
  ViewSpec spec;
  spec.view = View::kBoth;
  spec.width = 320;
  spec.height = 120;
  const fs::path out = TempDir("rendered") / "scene.mp4";
  FfmpegSink sink(out.string(), spec.width, spec.height, 25.0);
  Image img;
  for (int k = 0; k < 10; ++k) {
    state.camera.lens_roll_rad = 0.1 * k;
    renderer.Render(BuildScene(model, state), spec, &img);
    sink.Write(img);
  }
  sink.Close();
  const auto kv = Probe(out);
  EXPECT_EQ(kv.at("nb_read_frames"), "10");
  EXPECT_EQ(kv.at("width"), "320");
}

}  // namespace
}  // namespace arthrosim::render
