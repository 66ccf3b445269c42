#include "arthrosim/render/bench.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>

#include <unistd.h>

#include "arthrosim/render/renderer.h"
#include "arthrosim/render/scene.h"
#include "arthrosim/render/video_sink.h"

namespace arthrosim::render {

State MakeBenchmarkState(const Model& model) {
  State state = MakeInitialState(model);
  SceneScope scope;
  scope.pose = state.camera.pose;
  scope.lens_angle_rad = model.camera.lens_angle_deg * 3.14159265358979323846 / 180;
  const ViewFrame f = ScopeViewFrame(scope);
  const Vec3 right = f.forward.cross(f.up);
  const int n = std::min<int>(kToolSlots, static_cast<int>(model.instruments.size()));
  for (int slot = 0; slot < n; ++slot) {
    const double side = slot == 0 ? 1.0 : -1.0;
    ToolState& tool = state.tools[slot];
    tool.instrument = slot;
    tool.pose.position_mm = f.eye + (15.0 + 5.0 * slot) * f.forward + 4.0 * side * right;
    // enter from the side of the image, pointing across the view and away from the lens
    const Vec3 dir = (f.forward - 1.2 * side * right).normalized();
    tool.pose.orientation = Quat::FromTwoVectors(Vec3::UnitZ(), dir);
    tool.jaw = 0.5;
  }
  if (n > 0) state.tools[0].force_n = Vec3(0, 0, 2.0);
  return state;
}

double MeasureRenderFps(const Model& model, const State& state, int width, int height, int frames,
                        bool with_encoding) {
  if (frames < 1) throw std::invalid_argument("MeasureRenderFps: frames must be >= 1");
  Renderer renderer;
  ViewSpec spec;
  spec.width = width;
  spec.height = height;
  Image image;
  // warm-up: shader JIT, buffer allocation
  for (int i = 0; i < 2; ++i) renderer.Render(BuildScene(model, state), spec, &image);

  const std::string path = (std::filesystem::temp_directory_path() /
                            ("arthrosim_bench_" + std::to_string(::getpid()) + ".mp4"))
                               .string();
  std::unique_ptr<FfmpegSink> sink;
  if (with_encoding) sink = std::make_unique<FfmpegSink>(path, width, height, 25.0);
  // wall-clock timing is the point here; this is benchmark code, not simulation
  const auto t0 = std::chrono::steady_clock::now();
  for (int i = 0; i < frames; ++i) {
    const Scene scene = BuildScene(model, state);
    renderer.Render(scene, spec, &image);
    if (sink) sink->Write(image);
  }
  if (sink) sink->Close();
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::error_code ec;
  std::filesystem::remove(path, ec);
  return frames / seconds;
}

std::string RenderBenchReport(const Model& model, const State& state, int frames) {
  std::string out;
  for (const auto& [w, h] : {std::pair{640, 480}, std::pair{1280, 720}}) {
    const std::string size = std::to_string(w) + "x" + std::to_string(h);
    char line[128];
    std::snprintf(line, sizeof line, "render_fps_%s=%.1f\nvideo_fps_%s=%.1f\n", size.c_str(),
                  MeasureRenderFps(model, state, w, h, frames, false), size.c_str(),
                  MeasureRenderFps(model, state, w, h, frames, true));
    out += line;
  }
  return out;
}

}  // namespace arthrosim::render
