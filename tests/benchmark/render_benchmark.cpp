// Google Benchmark of rendering: BuildScene + Render (scope view with overlay) and the same
// with H.264 encoding through ffmpeg, at 640x480 and 1280x720. Uses the rotator-cuff anatomy
// (scenarios/rotator_cuff_repair.yaml) when it loads, else the synthetic scene of similar size
// (~6 000 bone triangles, 3 300 tets). Items per second = frames per second.
#include <benchmark/benchmark.h>

#include <cstdlib>
#include <filesystem>
#include <memory>

#include "arthrosim/io/scenario_loader.h"
#include "arthrosim/render/bench.h"
#include "arthrosim/render/renderer.h"
#include "arthrosim/render/synthetic_scene.h"
#include "arthrosim/render/video_sink.h"

namespace {

using namespace arthrosim;

struct Fixture {
  Model model;
  State state;
  std::string source;
};

const Fixture& Scene() {
  static const Fixture f = [] {
    Fixture out;
    const std::string path =
        std::string(ARTHROSIM_SOURCE_DIR) + "/scenarios/rotator_cuff_repair.yaml";
    try {
      out.model = io::LoadScenario(path);
      out.state = render::MakeBenchmarkState(out.model);
      out.source = "rotator_cuff_repair";
    } catch (const std::exception&) {
      out.state = render::MakeSyntheticScene({}, &out.model);
      out.source = "synthetic";
    }
    return out;
  }();
  return f;
}

void BM_BuildScene(benchmark::State& bench) {
  const Fixture& f = Scene();
  for (auto _ : bench) benchmark::DoNotOptimize(render::BuildScene(f.model, f.state));
  bench.SetItemsProcessed(bench.iterations());
  bench.SetLabel(f.source);
}
BENCHMARK(BM_BuildScene)->Unit(benchmark::kMillisecond);

// args: width, height, view (0 scope, 1 overview, 2 both), encode (0/1)
void BM_Render(benchmark::State& bench) {
  const Fixture& f = Scene();
  static render::Renderer renderer;
  render::ViewSpec spec;
  spec.width = static_cast<int>(bench.range(0));
  spec.height = static_cast<int>(bench.range(1));
  spec.view = static_cast<render::View>(bench.range(2));
  std::unique_ptr<render::FfmpegSink> sink;
  const std::string video =
      (std::filesystem::temp_directory_path() / "arthrosim_render_benchmark.mp4").string();
  if (bench.range(3) != 0)
    sink = std::make_unique<render::FfmpegSink>(video, spec.width, spec.height, 25.0);
  render::Image image;
  for (auto _ : bench) {
    renderer.Render(render::BuildScene(f.model, f.state), spec, &image);
    if (sink) sink->Write(image);
  }
  if (sink) sink->Close();  // the encoder's tail is part of the cost
  std::filesystem::remove(video);
  bench.SetItemsProcessed(bench.iterations());
  bench.SetLabel(f.source + " " + render::ViewName(spec.view) + (sink ? " +x264" : ""));
}
BENCHMARK(BM_Render)
    ->Args({640, 480, 0, 0})
    ->Args({640, 480, 1, 0})
    ->Args({1280, 480, 2, 0})
    ->Args({1280, 720, 0, 0})
    ->Args({640, 480, 0, 1})
    ->Args({1280, 720, 0, 1})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
