// Google Benchmark of the collision stage on the synthetic full scene (3 384 tets, 6 132 bone
// triangles, two 60-node threads, two instruments moving at 100 mm/s).
#include <benchmark/benchmark.h>

#include <cmath>

#include "arthrosim/collision/bench_scene.h"
#include "arthrosim/collision/contact_generation.h"
#include "arthrosim/core/units.h"

namespace {

using namespace arthrosim;

void BM_CollisionStage(benchmark::State& bench) {
  const Model model = collision::MakeBenchmarkModel();
  State state = MakeInitialState(model);
  const Points rest = state.soft_bodies[0].x;
  const Quat down(Eigen::AngleAxisd(units::kPi, Vec3::UnitX()));
  for (int slot = 0; slot < kToolSlots; ++slot) {
    state.tools[slot].instrument = slot;
    state.tools[slot].pose.orientation = down;
  }
  collision::CollisionParams params;
  collision::CollisionWorld world;
  collision::CollisionOutput out;
  int step = 0;
  for (auto _ : bench) {
    bench.PauseTiming();
    const auto prev = state.tools;
    const double x = 2.0 * (step % 16) - 16.0;  // 2 mm per 20 ms step
    state.tools[0].pose.position_mm = Vec3(x, -6, 28.5);
    state.tools[1].pose.position_mm = Vec3(-x, 6, 28.5);
    for (Eigen::Index i = 0; i < rest.cols(); ++i) {
      state.soft_bodies[0].x(2, i) = rest(2, i) + 0.3 * std::sin(0.2 * rest(0, i) + 0.3 * step);
    }
    ++step;
    bench.ResumeTiming();
    collision::Detect(model, state, prev, params, &world, &out);
    benchmark::DoNotOptimize(out.contacts.data());
  }
  bench.counters["contacts"] = static_cast<double>(out.contacts.size());
}
BENCHMARK(BM_CollisionStage)->Unit(benchmark::kMillisecond);

void BM_CollisionBenchFunction(benchmark::State& bench) {
  const Model model = collision::MakeBenchmarkModel();
  for (auto _ : bench) {
    const collision::CollisionBenchResult r = collision::BenchmarkCollision(model, 50);
    bench.counters["collision_ms_median"] = r.median_ms;
  }
}
BENCHMARK(BM_CollisionBenchFunction)->Unit(benchmark::kMillisecond)->Iterations(1);

}  // namespace

BENCHMARK_MAIN();
