#pragma once
// The cantilever-beam verification/benchmark scene shared by tests, the Google Benchmark
// target and `arthrosim bench`: 100 x 10 x 10 mm, E = 10 MPa, nu = 0.3, rho = 1000 kg/m^3,
// gravity 9.81 m/s^2 along -z, the x = 0 face fixed.
#include <functional>
#include <string>
#include <vector>

#include "arthrosim/core/mesh_types.h"
#include "arthrosim/core/model.h"
#include "arthrosim/core/state.h"
#include "arthrosim/physics/soft_system.h"

namespace arthrosim::physics {

/// Euler-Bernoulli tip deflection of the beam under its own weight, q L^4 / (8 E I), mm.
inline constexpr double kBeamEulerBernoulliTipMm = 1.4715;

/// A one-body Model of the beam on `mesh` (mm) with the given Rayleigh damping; nodes with
/// x <= 1e-6 mm are fixed. dt and solver options are the Model defaults.
Model MakeBeamModel(const mesh::TetMesh& mesh, double rayleigh_mass, double rayleigh_stiffness);

/// Mean z displacement (mm, negative = down) of the rest nodes on the x = 100 mm face.
double BeamTipDeflection(const State& state);

struct BeamBenchOptions {
  std::string mesh_path;  ///< e.g. tests/testdata/beam/beam_2.5.msh (3 573 tets)
  double dt_s = 0.02;
  int steps = 100;             ///< 2 s of simulated time at dt 0.02
  double rayleigh_mass = 0.1;  ///< SOFA example scenes' Rayleigh factors
  double rayleigh_stiffness = 0.1;
  int cg_max_iterations = 100;
  double cg_tolerance = 1e-8;
  SystemProduct product = SystemProduct::kAssembled;
  Integrator integrator = Integrator::kImplicitEuler;
};

struct BeamBenchResult {
  int nodes = 0, tets = 0, steps = 0;
  double ms_per_step = 0;         ///< mean CPU time of SoftSystem::Step (incl. refactorisations)
  double median_ms_per_step = 0;  ///< median CPU time of SoftSystem::Step
  double rotations_ms = 0, assembly_ms = 0, solve_ms = 0;  ///< means per step
  double mean_cg_iterations = 0;
  int max_cg_iterations = 0;
  double mean_cg_residual = 0;
  double static_tip_mm = 0;           ///< SolveStatic (linear) mean tip deflection
  double settled_tip_mm = 0;          ///< after the dynamic run
  double beam_settled_error_pct = 0;  ///< |settled - static| / |static| * 100
};

/// Loads the mesh, solves the static reference, runs `steps` dynamic steps from rest.
BeamBenchResult RunBeamBenchmark(const BeamBenchOptions& options);

/// Splits every alive tet of every soft body 1 -> 4 at its centroid, `levels` times (4^levels
/// tets; a scaling load, not a quality refinement). Velocities and warm starts are zeroed.
void RefineByCentroidSplits(State* state, int levels);

/// The soft-tissue step benchmark on a scenario's soft bodies (all of them, one system).
struct SoftBenchOptions {
  int warmup_steps = 10;  ///< not measured (the scene starts to sag from rest)
  int steps = 100;        ///< measured steps
  int refine_levels = 0;  ///< RefineByCentroidSplits levels (1 = 4x tets, 2 = 16x)
  /// A 0.5 N/mm spring (a grasper) drags the free node of the last soft body farthest from
  /// every fixed node around a circle of this radius (mm) in the y-z plane; 0 = idle scene.
  double drive_radius_mm = 3.0;
  double drive_period_s = 1.0;
  int refactor_iterations = -1;  ///< SolverOptions::refactor_iterations; -1 = the model's
  SystemProduct product = SystemProduct::kAssembled;  ///< how CG applies the system matrix
};

struct SoftBenchResult {
  int nodes = 0, tets = 0, steps = 0;
  double median_ms = 0;  ///< median CPU time of SoftSystem::Step
  double mean_ms = 0;    ///< mean CPU time (refactorisation steps included)
  double rotations_ms = 0, assembly_ms = 0, solve_ms = 0, update_ms = 0;  ///< stage medians
  double after_step_ms = 0;  ///< median CPU time of the caller's after_step hook (threads, output)
  double mean_cg_iterations = 0;
  int max_cg_iterations = 0;
  double final_cg_residual = 0;  ///< relative residual of the last step
  double max_cg_residual = 0;
  int refactorizations = 0;   ///< measured steps that factored the preconditioner
  double mean_factor_ms = 0;  ///< mean CPU time of one factorisation
};

/// Runs the scenario's soft bodies (threads single-threaded unless set by the caller's
/// SetThreadCount) for warmup + steps steps of model.options.dt_s. `after_step` (optional) runs
/// after each soft step on the state, e.g. the threads and output of `arthrosim bench`; its time
/// is reported apart. The Model's solver options apply.
SoftBenchResult RunSoftBenchmark(const Model& model, const SoftBenchOptions& options,
                                 const std::function<void(State*)>& after_step = {});

/// Everything `arthrosim bench SCENARIO` reports for the soft tissue (~5-10 s on one core).
struct FemBenchReport {
  SoftBenchResult idle;                ///< the scenario as is (hangs under gravity), 100 steps
  SoftBenchResult driven;              ///< with the SoftBenchOptions default drive, 100 steps
  SoftBenchResult driven_matrix_free;  ///< the same with the element-by-element product
  SoftBenchResult refined4;            ///< driven, 4x tets (RefineByCentroidSplits 1), 10 steps
  SoftBenchResult refined16;           ///< driven, 16x tets (RefineByCentroidSplits 2), 10 steps
  double beam_ms_per_step = 0;         ///< median CPU ms per step, beam_2.5 (3 573 tets)
  double beam_mean_ms_per_step = 0;    ///< mean (with its refactorisations)
  double beam_mean_cg_iterations = 0;
  double beam_settled_error_pct = 0;  ///< settled vs static tip deflection after 2 s
};

/// Runs the reports above; beam_mesh_path is e.g. <source>/tests/testdata/beam/beam_2.5.msh
/// (empty = skip the beam). after_step as in RunSoftBenchmark (timed apart).
FemBenchReport RunFemBenchSuite(const Model& model, const std::string& beam_mesh_path,
                                const std::function<void(State*)>& after_step = {});

}  // namespace arthrosim::physics
