// Soft-tissue step benchmarks: the cantilever beam (3 573 tets) and the bench_full scenario's
// supraspinatus muscle + tendon (joined, ~1 000 nodes / 3 300 tets), refined 4x and 16x by
// 1 -> 4 centroid splits. Counters: CG iterations, per-stage ms, final relative residual.
#include <benchmark/benchmark.h>

#include <string>

#include "arthrosim/core/parallel.h"
#include "arthrosim/io/scenario_loader.h"
#include "arthrosim/mesh/mesh_io.h"
#include "arthrosim/physics/fem_bench.h"
#include "arthrosim/physics/soft_system.h"

#ifndef ARTHROSIM_SOURCE_DIR
#define ARTHROSIM_SOURCE_DIR "."
#endif

namespace arthrosim::physics {
namespace {

std::string Source(const std::string& rel) { return std::string(ARTHROSIM_SOURCE_DIR) + "/" + rel; }

void Report(benchmark::State& bs, const SoftStepStats& sum, int steps, int nodes, int tets) {
  bs.counters["cg_it"] = static_cast<double>(sum.cg_iterations) / steps;
  bs.counters["rot_ms"] = sum.rotations_ms / steps;
  bs.counters["asm_ms"] = sum.assembly_ms / steps;
  bs.counters["solve_ms"] = sum.solve_ms / steps;
  bs.counters["residual"] = sum.cg_relative_residual / steps;
  bs.counters["nodes"] = nodes;
  bs.counters["tets"] = tets;
}

void RunSteps(benchmark::State& bs, const Model& model, State state, SystemProduct product,
              Preconditioner pre) {
  SetThreadCount(1);
  SoftSystem sys;
  sys.Build(model, state);
  sys.set_product(product);
  sys.set_preconditioner(pre);
  for (int k = 0; k < 20; ++k) sys.Step(model, nullptr, nullptr, &state);  // settle in a bit
  SoftStepStats sum;
  int steps = 0;
  for (auto _ : bs) {
    const SoftStepStats st = sys.Step(model, nullptr, nullptr, &state);
    sum.cg_iterations += st.cg_iterations;
    sum.rotations_ms += st.rotations_ms;
    sum.assembly_ms += st.assembly_ms;
    sum.solve_ms += st.solve_ms;
    sum.cg_relative_residual += st.cg_relative_residual;
    ++steps;
  }
  int nodes = 0, tets = 0;
  for (const SoftBodyState& b : state.soft_bodies) {
    nodes += static_cast<int>(b.x.cols());
    tets += static_cast<int>(b.tets.size());
  }
  Report(bs, sum, std::max(1, steps), nodes, tets);
}

// Arg 0: product (0 assembled, 1 matrix-free); arg 1: preconditioner (0 block-Jacobi,
// 1 warped rest Cholesky).
void BM_BeamStep(benchmark::State& bs) {
  Model model =
      MakeBeamModel(mesh::ReadTetMesh(Source("tests/testdata/beam/beam_2.5.msh")), 0.1, 0.1);
  RunSteps(bs, model, MakeInitialState(model), static_cast<SystemProduct>(bs.range(0)),
           static_cast<Preconditioner>(bs.range(1)));
}
BENCHMARK(BM_BeamStep)
    ->Args({0, 1})
    ->Args({1, 1})
    ->Args({0, 0})
    ->Args({1, 0})
    ->Unit(benchmark::kMillisecond);

// Arg 0: refinement levels (0, 1 = 4x tets, 2 = 16x tets); arg 1: preconditioner.
void BM_CuffStep(benchmark::State& bs) {
  Model model = io::LoadScenario(Source("scenarios/bench_full.yaml"));
  State state = MakeInitialState(model);
  RefineByCentroidSplits(&state, static_cast<int>(bs.range(0)));
  RunSteps(bs, model, std::move(state), SystemProduct::kAssembled,
           static_cast<Preconditioner>(bs.range(1)));
}
BENCHMARK(BM_CuffStep)
    ->Args({0, 1})
    ->Args({1, 1})
    ->Args({2, 1})
    ->Args({0, 0})
    ->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace arthrosim::physics

BENCHMARK_MAIN();
