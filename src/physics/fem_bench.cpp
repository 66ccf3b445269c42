#include "arthrosim/physics/fem_bench.h"

#include <algorithm>
#include <cmath>
#include <ctime>
#include <limits>

#include "arthrosim/mesh/mesh_io.h"

namespace arthrosim::physics {
namespace {

double CpuMs() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return 1e3 * static_cast<double>(ts.tv_sec) + 1e-6 * static_cast<double>(ts.tv_nsec);
}

double Median(std::vector<double> v) {
  if (v.empty()) return 0;
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

}  // namespace

Model MakeBeamModel(const mesh::TetMesh& mesh, double rayleigh_mass, double rayleigh_stiffness) {
  Model model;
  model.name = "cantilever_beam";
  Material mat;
  mat.name = "beam";
  mat.young_modulus_pa = 10e6;
  mat.poisson_ratio = 0.3;
  mat.density_kg_m3 = 1000;
  mat.rayleigh_mass = rayleigh_mass;
  mat.rayleigh_stiffness = rayleigh_stiffness;
  model.materials.push_back(mat);
  SoftBodyModel body;
  body.name = "beam";
  body.rest_mesh = mesh;
  body.material = mat;
  for (Eigen::Index i = 0; i < mesh.nodes.cols(); ++i) {
    if (mesh.nodes(0, i) <= 1e-6) body.fixed_nodes.push_back(static_cast<std::int32_t>(i));
  }
  model.soft_bodies.push_back(std::move(body));
  model.options.gravity_mm_s2 = Vec3(0, 0, -9810.0);
  return model;
}

double BeamTipDeflection(const State& state) {
  const SoftBodyState& b = state.soft_bodies.at(0);
  double sum = 0;
  int n = 0;
  for (Eigen::Index i = 0; i < b.x_rest.cols(); ++i) {
    if (b.x_rest(0, i) >= 100.0 - 1e-6) {
      sum += b.x(2, i) - b.x_rest(2, i);
      ++n;
    }
  }
  return n ? sum / n : 0.0;
}

BeamBenchResult RunBeamBenchmark(const BeamBenchOptions& options) {
  const mesh::TetMesh mesh = mesh::ReadTetMesh(options.mesh_path);
  Model model = MakeBeamModel(mesh, options.rayleigh_mass, options.rayleigh_stiffness);
  model.options.dt_s = options.dt_s;
  model.solver.cg_max_iterations = options.cg_max_iterations;
  model.solver.cg_tolerance = options.cg_tolerance;
  model.solver.integrator = options.integrator;
  model.solver.product = options.product;
  BeamBenchResult r;
  r.nodes = static_cast<int>(mesh.nodes.cols());
  r.tets = static_cast<int>(mesh.tets.size());

  SoftSystem sys;
  {
    State s = MakeInitialState(model);
    sys.Build(model, s);
    sys.SolveStatic(model, &s, 1);
    r.static_tip_mm = BeamTipDeflection(s);
  }
  State state = MakeInitialState(model);
  sys.Build(model, state);
  double total = 0;
  std::vector<double> per_step;
  for (int i = 0; i < options.steps; ++i) {
    const SoftStepStats st = sys.Step(model, nullptr, nullptr, &state);
    state.time_s += model.options.dt_s;
    ++state.step;
    total += st.total_ms;
    per_step.push_back(st.total_ms);
    r.rotations_ms += st.rotations_ms;
    r.assembly_ms += st.assembly_ms;
    r.solve_ms += st.solve_ms;
    r.mean_cg_iterations += st.cg_iterations;
    r.max_cg_iterations = std::max(r.max_cg_iterations, st.cg_iterations);
    r.mean_cg_residual += st.cg_relative_residual;
  }
  const double n = std::max(1, options.steps);
  r.steps = options.steps;
  r.ms_per_step = total / n;
  r.median_ms_per_step = Median(per_step);
  r.rotations_ms /= n;
  r.assembly_ms /= n;
  r.solve_ms /= n;
  r.mean_cg_iterations /= n;
  r.mean_cg_residual /= n;
  r.settled_tip_mm = BeamTipDeflection(state);
  r.beam_settled_error_pct =
      r.static_tip_mm != 0
          ? 100.0 * std::abs(r.settled_tip_mm - r.static_tip_mm) / std::abs(r.static_tip_mm)
          : 0.0;
  return r;
}

void RefineByCentroidSplits(State* state, int levels) {
  for (int l = 0; l < levels; ++l) {
    for (SoftBodyState& b : state->soft_bodies) {
      const auto n0 = b.x.cols();
      std::vector<mesh::Tet> tets;
      std::vector<Vec3> x, xr;
      for (std::size_t t = 0; t < b.tets.size(); ++t) {
        if (!b.tet_alive[t]) continue;
        const mesh::Tet& p = b.tets[t];
        Vec3 c = Vec3::Zero(), cr = Vec3::Zero();
        for (std::int32_t k : p) {
          c += 0.25 * b.x.col(k);
          cr += 0.25 * b.x_rest.col(k);
        }
        const auto q = static_cast<std::int32_t>(n0 + static_cast<Eigen::Index>(x.size()));
        x.push_back(c);
        xr.push_back(cr);
        tets.push_back({q, p[1], p[2], p[3]});
        tets.push_back({p[0], q, p[2], p[3]});
        tets.push_back({p[0], p[1], q, p[3]});
        tets.push_back({p[0], p[1], p[2], q});
      }
      const auto n = n0 + static_cast<Eigen::Index>(x.size());
      b.x.conservativeResize(3, n);
      b.x_rest.conservativeResize(3, n);
      for (std::size_t i = 0; i < x.size(); ++i) {
        b.x.col(n0 + static_cast<Eigen::Index>(i)) = x[i];
        b.x_rest.col(n0 + static_cast<Eigen::Index>(i)) = xr[i];
      }
      b.v = Points::Zero(3, n);
      b.dv_warm = Points::Zero(3, n);
      b.x_factor.resize(3, 0);
      b.factor_rest.resize(3, 0);
      b.factor_alive.clear();
      b.tets = std::move(tets);
      b.tet_alive.assign(b.tets.size(), 1);
    }
  }
}

SoftBenchResult RunSoftBenchmark(const Model& scenario, const SoftBenchOptions& options,
                                 const std::function<void(State*)>& after_step) {
  SoftBenchResult r;
  if (scenario.soft_bodies.empty()) return r;
  Model model = scenario;  // with the benchmark's solver settings
  if (options.refactor_iterations >= 0) {
    model.solver.refactor_iterations = options.refactor_iterations;
  }
  model.solver.product = options.product;
  State state = MakeInitialState(model);
  RefineByCentroidSplits(&state, options.refine_levels);
  SoftSystem sys;
  sys.Build(model, state);
  for (const SoftBodyState& b : state.soft_bodies) {
    r.nodes += static_cast<int>(b.x.cols());
    r.tets += static_cast<int>(b.tets.size());
  }

  // The driven node: in the last soft body, farthest (at rest) from every fixed node of every
  // body; ties by lower index.
  SpringSet springs;
  Vec3 centre = Vec3::Zero();
  if (options.drive_radius_mm > 0) {
    std::vector<Vec3> fixed;
    for (std::size_t b = 0; b < model.soft_bodies.size(); ++b) {
      for (std::int32_t k : model.soft_bodies[b].fixed_nodes)
        fixed.push_back(state.soft_bodies[b].x_rest.col(k));
    }
    const auto last = static_cast<int>(state.soft_bodies.size()) - 1;
    const SoftBodyState& sb = state.soft_bodies[static_cast<std::size_t>(last)];
    std::int32_t best = -1;
    double best_d = -1;
    for (Eigen::Index i = 0; i < sb.x_rest.cols(); ++i) {
      if (!sys.IsFree(last, static_cast<std::int32_t>(i))) continue;
      double d = fixed.empty() ? 0.0 : std::numeric_limits<double>::infinity();
      for (const Vec3& f : fixed) d = std::min(d, (sb.x_rest.col(i) - f).norm());
      if (d > best_d) {
        best_d = d;
        best = static_cast<std::int32_t>(i);
      }
    }
    if (best >= 0) {
      PointSpring sp;
      sp.index = last;
      sp.nodes = {best, -1, -1, -1};
      sp.weights = {1, 0, 0, 0};
      sp.stiffness_n_per_mm = 0.5;
      centre = sb.x_rest.col(best);
      sp.anchor_mm = centre;
      springs.push_back(sp);
    }
  }

  std::vector<double> total, rot, assembly, solve, update, hook;
  double factor_sum = 0;
  const int n_all = options.warmup_steps + options.steps;
  for (int k = 0; k < n_all; ++k) {
    if (!springs.empty()) {
      const double phase = 2.0 * 3.14159265358979323846 * state.time_s / options.drive_period_s;
      springs[0].anchor_mm =
          centre + options.drive_radius_mm * Vec3(0, std::sin(phase), 1.0 - std::cos(phase));
    }
    const SoftStepStats st = sys.Step(model, nullptr, &springs, &state);
    double hook_ms = 0;
    if (after_step) {
      const double t0 = CpuMs();
      after_step(&state);
      hook_ms = CpuMs() - t0;
    }
    state.time_s += model.options.dt_s;
    ++state.step;
    if (k < options.warmup_steps) continue;
    total.push_back(st.total_ms);
    rot.push_back(st.rotations_ms);
    assembly.push_back(st.assembly_ms);
    solve.push_back(st.solve_ms);
    update.push_back(st.update_ms);
    hook.push_back(hook_ms);
    r.mean_cg_iterations += st.cg_iterations;
    r.max_cg_iterations = std::max(r.max_cg_iterations, st.cg_iterations);
    r.final_cg_residual = st.cg_relative_residual;
    r.max_cg_residual = std::max(r.max_cg_residual, st.cg_relative_residual);
    if (st.refactored) {
      ++r.refactorizations;
      factor_sum += st.factor_ms;
    }
  }
  r.steps = options.steps;
  const double n = std::max(1, options.steps);
  for (double t : total) r.mean_ms += t / n;
  r.median_ms = Median(total);
  r.rotations_ms = Median(rot);
  r.assembly_ms = Median(assembly);
  r.solve_ms = Median(solve);
  r.update_ms = Median(update);
  r.after_step_ms = Median(hook);
  r.mean_cg_iterations /= n;
  r.mean_factor_ms = r.refactorizations ? factor_sum / r.refactorizations : 0.0;
  return r;
}

FemBenchReport RunFemBenchSuite(const Model& model, const std::string& beam_mesh_path,
                                const std::function<void(State*)>& after_step) {
  FemBenchReport r;
  SoftBenchOptions idle;
  idle.drive_radius_mm = 0;
  r.idle = RunSoftBenchmark(model, idle, after_step);
  r.driven = RunSoftBenchmark(model, SoftBenchOptions{}, after_step);
  SoftBenchOptions matrix_free;
  matrix_free.product = SystemProduct::kMatrixFree;
  r.driven_matrix_free = RunSoftBenchmark(model, matrix_free, after_step);
  SoftBenchOptions fine;
  fine.warmup_steps = 5;
  fine.steps = 10;
  fine.refine_levels = 1;
  r.refined4 = RunSoftBenchmark(model, fine, after_step);
  fine.refine_levels = 2;
  r.refined16 = RunSoftBenchmark(model, fine, after_step);
  if (!beam_mesh_path.empty()) {
    BeamBenchOptions beam;
    beam.mesh_path = beam_mesh_path;
    const BeamBenchResult b = RunBeamBenchmark(beam);
    r.beam_ms_per_step = b.median_ms_per_step;
    r.beam_mean_ms_per_step = b.ms_per_step;
    r.beam_mean_cg_iterations = b.mean_cg_iterations;
    r.beam_settled_error_pct = b.beam_settled_error_pct;
  }
  return r;
}

}  // namespace arthrosim::physics
