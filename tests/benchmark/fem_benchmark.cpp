// Soft-tissue step benchmarks: the cantilever beam (3 573 tets) and the bench_full scenario's
// supraspinatus muscle + tendon (joined, ~1 000 nodes / 3 300 tets), refined 4x and 16x by
// 1 -> 4 centroid splits. Counters: CG iterations, per-stage ms, final relative residual.
#include <benchmark/benchmark.h>

#include <string>

#include "arthrosim/core/parallel.h"
#include "arthrosim/io/scenario_loader.h"
#include "arthrosim/mesh/mesh_io.h"
#include "arthrosim/physics/block_ldlt.h"
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

void RunSteps(benchmark::State& bs, const Model& scenario, State state, SystemProduct product,
              Preconditioner pre) {
  SetThreadCount(1);
  Model model = scenario;
  model.solver.product = product;
  model.solver.preconditioner = pre;
  SoftSystem sys;
  sys.Build(model, state);
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

// The preconditioner's factor alone, on the supraspinatus muscle's node graph (613 nodes):
// an SPD block matrix with the step matrix's pattern (edge blocks of a vector Laplacian plus a
// mass-like diagonal). Arg 0: 0 = numeric factorisation, 1 = one solve.
void BM_MuscleFactor(benchmark::State& bs) {
  const mesh::TetMesh m = mesh::ReadTetMesh(Source("scenarios/meshes/supraspinatus_muscle.msh"));
  const auto n = static_cast<std::int32_t>(m.nodes.cols());
  std::vector<std::array<std::int32_t, 2>> pairs;
  for (const mesh::Tet& t : m.tets)
    for (int a = 0; a < 4; ++a)
      for (int b = a + 1; b < 4; ++b) pairs.push_back({std::min(t[a], t[b]), std::max(t[a], t[b])});
  std::sort(pairs.begin(), pairs.end());
  pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
  std::vector<Mat3> diag(static_cast<std::size_t>(n), 0.01 * Mat3::Identity());
  std::vector<Mat3> off(pairs.size());
  for (std::size_t e = 0; e < pairs.size(); ++e) {
    const Vec3 d = m.nodes.col(pairs[e][1]) - m.nodes.col(pairs[e][0]);
    const Mat3 k = Mat3::Identity() + d * d.transpose() / d.squaredNorm();
    off[e] = -k;
    diag[static_cast<std::size_t>(pairs[e][0])] += k;
    diag[static_cast<std::size_t>(pairs[e][1])] += k;
  }
  BlockLdlt ldlt;
  ldlt.Analyze(n, pairs);
  ldlt.Factor(diag, off);
  Eigen::VectorXd x = Eigen::VectorXd::Ones(3 * n);
  for (auto _ : bs) {
    if (bs.range(0) == 0) {
      benchmark::DoNotOptimize(ldlt.Factor(diag, off));
    } else {
      ldlt.Solve(x.data());
      benchmark::DoNotOptimize(x.data());
    }
  }
  bs.counters["factor_nnz"] = static_cast<double>(ldlt.factor_nonzeros());
}
BENCHMARK(BM_MuscleFactor)->Arg(0)->Arg(1)->Unit(benchmark::kMicrosecond);

}  // namespace
}  // namespace arthrosim::physics

BENCHMARK_MAIN();
