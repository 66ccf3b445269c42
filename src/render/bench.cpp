#include "arthrosim/render/bench.h"

#include <chrono>
#include <filesystem>
#include <memory>
#include <stdexcept>
#include <string>

#include <unistd.h>

#include "arthrosim/render/renderer.h"
#include "arthrosim/render/scene.h"
#include "arthrosim/render/video_sink.h"

namespace arthrosim::render {

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

}  // namespace arthrosim::render
