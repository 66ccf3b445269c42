#include "arthrosim/physics/fem_bench.h"

#include <algorithm>
#include <cmath>

#include "arthrosim/mesh/mesh_io.h"

namespace arthrosim::physics {

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
  sys.set_product(options.product);
  double total = 0;
  for (int i = 0; i < options.steps; ++i) {
    const SoftStepStats st = sys.Step(model, nullptr, nullptr, &state);
    state.time_s += model.options.dt_s;
    ++state.step;
    total += st.total_ms;
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

}  // namespace arthrosim::physics
