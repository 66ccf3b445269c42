#include "arthrosim/render/bench.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>

#include <sys/resource.h>
#include <time.h>
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

namespace {

// CPU seconds of this process (all threads) and of its waited-for children.
double ProcessCpuSeconds() {
  timespec t{};
  ::clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

double ChildrenCpuSeconds() {
  rusage u{};
  ::getrusage(RUSAGE_CHILDREN, &u);
  auto sec = [](const timeval& v) { return static_cast<double>(v.tv_sec) + 1e-6 * v.tv_usec; };
  return sec(u.ru_utime) + sec(u.ru_stime);
}

}  // namespace

double MeasureRenderFps(const Model& model, const State& state, int width, int height, int frames,
                        bool with_encoding) {
  return MeasureRender(model, state, width, height, frames, with_encoding).fps;
}

RenderThroughput MeasureRender(const Model& model, const State& state, int width, int height,
                               int frames, bool with_encoding) {
  if (frames < 1) throw std::invalid_argument("MeasureRender: frames must be >= 1");
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
  const double cpu0 = ProcessCpuSeconds(), child0 = ChildrenCpuSeconds();
  for (int i = 0; i < frames; ++i) {
    const Scene scene = BuildScene(model, state);
    renderer.Render(scene, spec, &image);
    if (sink) sink->Write(image);
  }
  if (sink) sink->Close();  // waits for ffmpeg, so its CPU time is in RUSAGE_CHILDREN
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  RenderThroughput out;
  out.fps = frames / seconds;
  out.cpu_ms_per_frame = 1e3 * (ProcessCpuSeconds() - cpu0) / frames;
  out.ffmpeg_ms_per_frame = 1e3 * (ChildrenCpuSeconds() - child0) / frames;
  std::error_code ec;
  std::filesystem::remove(path, ec);
  return out;
}

std::string RenderBenchReport(const Model& model, const State& state, int frames) {
  std::string out;
  for (const auto& [w, h] : {std::pair{640, 480}, std::pair{1280, 720}}) {
    const std::string size = std::to_string(w) + "x" + std::to_string(h);
    const RenderThroughput r = MeasureRender(model, state, w, h, frames, false);
    const RenderThroughput v = MeasureRender(model, state, w, h, frames, true);
    char line[512];
    std::snprintf(line, sizeof line,
                  "render_fps_%s=%.1f\nrender_cpu_ms_%s=%.2f\nvideo_fps_%s=%.1f\n"
                  "video_cpu_ms_%s=%.2f\nvideo_ffmpeg_cpu_ms_%s=%.2f\n",
                  size.c_str(), r.fps, size.c_str(), r.cpu_ms_per_frame, size.c_str(), v.fps,
                  size.c_str(), v.cpu_ms_per_frame, size.c_str(), v.ffmpeg_ms_per_frame);
    out += line;
  }
  return out;
}

}  // namespace arthrosim::render
