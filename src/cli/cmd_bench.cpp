// arthrosim bench SCENARIO [--steps N] [--trajectory F] [--abusive F] [--ops-dir D]
//                          [--beam-mesh F] [--trace F.csv] [--render]
// Times the step stage by stage on one thread and prints a table plus one name=value line per
// figure (for scripts). Also runs the cantilever beam of the physics verification (speed at
// equal accuracy: ms per step and how far the settled tip is from the static solution).
#include <fmt/core.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <memory>
#include <numeric>
#include <vector>

#include "arthrosim/collision/bench_scene.h"
#include "arthrosim/core/error.h"
#include "arthrosim/core/parallel.h"
#include "arthrosim/input/open_source.h"
#include "arthrosim/io/run_writer.h"
#include "arthrosim/io/scenario_loader.h"
#include "arthrosim/physics/fem_bench.h"
#include "arthrosim/render/bench.h"
#include "arthrosim/sim/step.h"
#include "commands.h"

namespace arthrosim::cli {
namespace {

struct BenchArgs {
  std::string scenario, trajectory, beam_mesh = "tests/testdata/beam/beam_2.5.msh";
  std::string abusive = "trajectories/abusive_sweep.yaml", ops_dir = "trajectories/ops";
  std::string trace;  // per-step CSV of the main figures' steps (empty: none)
  int steps = 100;
  int threads = 1;
  bool render = false;
};

double Median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

double Mean(const std::vector<double>& v) {
  return v.empty() ? 0 : std::accumulate(v.begin(), v.end(), 0.0) / static_cast<double>(v.size());
}

// The q-quantile (0..1) by the nearest-rank method; 0 for no samples.
double Quantile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const auto rank = static_cast<std::size_t>(std::ceil(q * static_cast<double>(v.size())));
  return v[std::clamp<std::size_t>(rank, 1, v.size()) - 1];
}

// CPU time of the calling thread, ms: unlike wall time, not inflated when the thread is
// preempted on a loaded machine.
double ThreadCpuMs() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) * 1e3 + static_cast<double>(t.tv_nsec) * 1e-6;
}

double Max(const std::vector<double>& v) {
  return v.empty() ? 0 : *std::max_element(v.begin(), v.end());
}

struct Series {
  std::vector<double> step, kinematics, collision, rotations, assembly, solve, thread, output,
      cg_it, physics;              // physics: soft tissue + threads (the step without collision)
  std::vector<double> output_cpu;  // CPU time of this thread in the output step
  double last_residual = 0;
  int refactors = 0;                // steps that took a new preconditioner factor into use
  int factor_steps = 0;             // steps that did factor work (a whole factor or a part)
  double refactor_ms = 0;           // total factor work time
  double factor_ms_max = 0;         // most factor work in one step
  std::vector<std::uint8_t> holds;  // per timed step: bit s set = slot s holds `instrument`
  double cg_it_max = 0;
  int retried_steps = 0;      // steps whose solve diverged and was redone in substeps
  double max_node_speed = 0;  // fastest soft-tissue or thread node after any step, mm/s
};

// Times `steps` steps of the trajectory (< 0: until it is finished, at most 100 000) after a
// short warm-up; `instrument` (or -1) marks the steps where a slot holds it.
// `trace` (or null): one CSV row per timed step (docs in AddBenchCommand's --trace).
Series TimeScenario(const Model& model, const std::string& trajectory, int steps,
                    int instrument = -1, std::FILE* trace = nullptr) {
  input::SourceOptions options;
  options.dt_s = model.options.dt_s;
  auto source = input::OpenInputSource(trajectory.empty() ? "none" : trajectory, model, options);
  State state = MakeInitialState(model);
  sim::Workspace ws;
  sim::BuildWorkspace(model, state, &ws);
  const std::string out = (std::filesystem::temp_directory_path() / "arthrosim_bench.h5").string();
  io::RunWriter writer(out, model, state);
  Series s;
  InputFrame frame;
  constexpr int kWarmup = 3;
  const int total = steps >= 0 ? steps + kWarmup : 100000;
  for (int k = 0; k < total; ++k) {
    if (steps < 0 && source->Finished(static_cast<double>(state.step + 1) * model.options.dt_s)) {
      break;
    }
    source->Frame(state.step + 1, static_cast<double>(state.step + 1) * model.options.dt_s, &frame);
    sim::Step(model, frame, &state, &ws);
    source->Feedback(sim::Feedback(state));
    const double cpu0_ms = ThreadCpuMs();
    const auto t0 = std::chrono::steady_clock::now();
    writer.Append(state);
    const double output_ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    const double output_cpu_ms = ThreadCpuMs() - cpu0_ms;
    if (k < kWarmup) continue;
    const sim::StepTimings& t = ws.timings;
    s.step.push_back(t.total_ms);
    s.kinematics.push_back(t.kinematics_ms);
    s.collision.push_back(t.collision_ms);
    s.rotations.push_back(t.soft.rotations_ms);
    s.assembly.push_back(t.soft.assembly_ms);
    s.solve.push_back(t.soft.solve_ms);
    s.thread.push_back(t.thread_ms);
    s.physics.push_back(t.soft_ms + t.thread_ms);
    s.output.push_back(output_ms);
    s.output_cpu.push_back(output_cpu_ms);
    s.cg_it.push_back(t.soft.cg_iterations);
    s.cg_it_max = std::max(s.cg_it_max, static_cast<double>(t.soft.cg_iterations));
    s.retried_steps += t.substeps > 1 ? 1 : 0;
    s.max_node_speed = std::max(s.max_node_speed, t.max_node_speed_mm_s);
    std::uint8_t holds = 0;
    for (int slot = 0; slot < kToolSlots; ++slot) {
      if (instrument >= 0 && state.tools[slot].instrument == instrument) holds |= 1u << slot;
    }
    s.holds.push_back(holds);
    if (trace != nullptr) {
      fmt::print(trace,
                 "{},{:.4f},{:.4f},{:.4f},{:.4f},{:.4f},{:.4f},{:.4f},{:.4f},{:.4f},{},{},{},{},{},"
                 "{},{},{:.4f},{:.4f}\n",
                 state.step, t.total_ms, t.kinematics_ms, t.collision_ms, t.soft.rotations_ms,
                 t.soft.assembly_ms, t.soft.factor_ms, t.soft.solve_ms, t.thread_ms,
                 t.instruments_ms, t.soft.cg_iterations, t.soft.contact_resolves,
                 t.soft.active_contacts, t.soft.refactored ? 1 : 0, t.soft.anchor_moved ? 1 : 0,
                 ws.threads.last.newton_iterations, ws.threads.last.unconverged_solves, output_ms,
                 output_cpu_ms);
    }
    s.last_residual = t.soft.cg_relative_residual;
    s.refactors += t.soft.refactored ? 1 : 0;
    if (t.soft.factor_work) {
      ++s.factor_steps;
      s.refactor_ms += t.soft.factor_ms;
      s.factor_ms_max = std::max(s.factor_ms_max, t.soft.factor_ms);
    }
  }
  writer.Close();
  std::filesystem::remove(out);
  std::filesystem::remove(std::filesystem::path(out).replace_extension(".xmf"));
  return s;
}

void PrintScenario(const Model& model, const Series& s, int steps) {
  std::size_t nodes = 0, tets = 0, thread_nodes = 0;
  for (const auto& b : model.soft_bodies) {
    nodes += static_cast<std::size_t>(b.rest_mesh.nodes.cols());
    tets += b.rest_mesh.tets.size();
  }
  for (const auto& t : model.threads)
    thread_nodes += static_cast<std::size_t>(t.initial.nodes.cols());
  fmt::print(
      "scenario {}: {} soft nodes (before joins), {} tets, {} sutures ({} nodes), dt {} s, "
      "{} timed steps, {} worker thread(s)\n",
      model.name, nodes, tets, model.threads.size(), thread_nodes, model.options.dt_s, steps,
      ThreadCount());
  fmt::print("  {:12} {:>10} {:>10}\n", "stage", "median ms", "mean ms");
  const std::pair<const char*, const std::vector<double>*> rows[] = {
      {"kinematics", &s.kinematics}, {"collision", &s.collision}, {"rotations", &s.rotations},
      {"assembly", &s.assembly},     {"solve", &s.solve},         {"thread", &s.thread},
      {"physics", &s.physics},       {"step total", &s.step},     {"output", &s.output}};
  for (const auto& [name, v] : rows)
    fmt::print("  {:12} {:10.3f} {:10.3f}\n", name, Median(*v), Mean(*v));
  fmt::print("step_ms_median={:.3f}\n", Median(s.step));
  fmt::print("physics_step_ms_median={:.3f}\n", Median(s.physics));
  fmt::print("step_collision_ms_median={:.3f}\n", Median(s.collision));
  fmt::print("rotations_ms_median={:.3f}\n", Median(s.rotations));
  fmt::print("assembly_ms_median={:.3f}\n", Median(s.assembly));
  fmt::print("solve_ms_median={:.3f}\n", Median(s.solve));
  fmt::print("thread_ms_median={:.3f}\n", Median(s.thread));
  fmt::print("output_ms_median={:.3f}\n", Median(s.output));
  // the flushes: once per output.flush_interval, the worst output steps
  fmt::print("output_ms_mean={:.3f}\noutput_ms_max={:.3f}\n", Mean(s.output), Max(s.output));
  // the same in CPU time of the stepping thread (the run writer's own thread is not counted)
  fmt::print("output_cpu_ms_median={:.3f}\noutput_cpu_ms_mean={:.3f}\noutput_cpu_ms_max={:.3f}\n",
             Median(s.output_cpu), Mean(s.output_cpu), Max(s.output_cpu));
  fmt::print("cg_iterations_mean={:.2f}\n", Mean(s.cg_it));
  fmt::print("cg_residual_final={:.3g}\n", s.last_residual);
  fmt::print("step_ms_mean={:.3f}\n", Mean(s.step));
  fmt::print("refactors={}\nrefactor_ms_mean={:.3f}\n", s.refactors,
             s.refactors ? s.refactor_ms / s.refactors : 0.0);
  fmt::print("factor_work_steps={}\nfactor_work_ms_max={:.3f}\n", s.factor_steps, s.factor_ms_max);
  fmt::print("step_ms_p99={:.3f}\nstep_ms_max={:.3f}\n", Quantile(s.step, 0.99), Max(s.step));
  fmt::print("solver_retry_steps={}\nmax_node_speed_mm_s={:.1f}\n", s.retried_steps,
             s.max_node_speed);
}

// The abusive replay: a tool swept through the anatomy (mean, p99 and worst step beside the
// median: what a trainee feels is the worst step, not the median one).
void PrintAbusive(const Model& model, const std::string& trajectory) {
  if (!std::filesystem::exists(trajectory)) {
    fmt::print("abusive replay: skipped ({} not found; run from the source tree)\n", trajectory);
    return;
  }
  const Series s = TimeScenario(model, trajectory, -1);
  fmt::print("abusive replay {}: {} steps\n", trajectory, s.step.size());
  fmt::print("abusive_step_ms_median={:.3f}\nabusive_step_ms_mean={:.3f}\n", Median(s.step),
             Mean(s.step));
  fmt::print("abusive_step_ms_p99={:.3f}\nabusive_step_ms_max={:.3f}\n", Quantile(s.step, 0.99),
             Max(s.step));
  fmt::print("abusive_cg_iterations_mean={:.2f}\nabusive_cg_iterations_max={:.0f}\n", Mean(s.cg_it),
             s.cg_it_max);
  fmt::print("abusive_refactors_per_1000_steps={:.1f}\n",
             s.step.empty() ? 0.0 : 1000.0 * s.refactors / static_cast<double>(s.step.size()));
  fmt::print("abusive_factor_work_ms_max={:.3f}\n", s.factor_ms_max);
  fmt::print("abusive_solver_retry_steps={}\nabusive_max_node_speed_mm_s={:.1f}\n", s.retried_steps,
             s.max_node_speed);
}

// One pair of figures per operation trajectory (ops_dir/<instrument>.yaml): the median and the
// worst step among the steps where a slot holds that instrument.
void PrintOperations(const Model& model, const std::string& ops_dir) {
  if (!std::filesystem::is_directory(ops_dir)) return;
  std::vector<std::filesystem::path> files;
  for (const auto& e : std::filesystem::directory_iterator(ops_dir)) {
    if (e.path().extension() == ".yaml") files.push_back(e.path());
  }
  std::sort(files.begin(), files.end());
  for (const std::filesystem::path& f : files) {
    const std::string name = f.stem().string();
    const int instrument = model.FindInstrument(name);
    if (instrument < 0) {
      fmt::print("op {}: skipped (no instrument of that name in the scenario)\n", name);
      continue;
    }
    const Series s = TimeScenario(model, f.string(), -1, instrument);
    std::vector<double> held;
    for (std::size_t k = 0; k < s.step.size(); ++k) {
      if (s.holds[k] != 0) held.push_back(s.step[k]);
    }
    fmt::print("op_{}_median_step_ms={:.3f}\nop_{}_worst_step_ms={:.3f}\n", name, Median(held),
               name, Max(held));
  }
}

// Soft tissue alone (CPU time): idle and driven by a grasper-like spring, refined 4x and 16x,
// and the cantilever beam at equal accuracy (settled tip vs the static solution).
void PrintSoftSuite(const Model& model, const std::string& beam_mesh) {
  const bool have_beam = std::filesystem::exists(beam_mesh);
  const physics::FemBenchReport r = physics::RunFemBenchSuite(model, have_beam ? beam_mesh : "");
  auto line = [](const char* name, const physics::SoftBenchResult& s) {
    fmt::print(
        "  {:10} {:6} tets  median {:7.3f} ms  mean {:7.3f} ms  CG {:5.1f} it (max {})  "
        "refactors {} x {:.1f} ms\n",
        name, s.tets, s.median_ms, s.mean_ms, s.mean_cg_iterations, s.max_cg_iterations,
        s.refactorizations, s.mean_factor_ms);
  };
  fmt::print("soft tissue alone (CPU time per step):\n");
  line("idle", r.idle);
  line("driven", r.driven);
  line("driven mf", r.driven_matrix_free);
  line("driven 4x", r.refined4);
  line("driven 16x", r.refined16);
  fmt::print(
      "soft_ms_median_idle={:.3f}\nsoft_ms_median_driven={:.3f}\nsoft_ms_mean_driven={:.3f}\n",
      r.idle.median_ms, r.driven.median_ms, r.driven.mean_ms);
  fmt::print("soft_ms_median_driven_matrix_free={:.3f}\n", r.driven_matrix_free.median_ms);
  fmt::print("soft_ms_median_4x={:.3f}\nsoft_ms_median_16x={:.3f}\n", r.refined4.median_ms,
             r.refined16.median_ms);
  if (!have_beam) {
    fmt::print("beam: skipped (mesh {} not found; run from the source tree or pass --beam-mesh)\n",
               beam_mesh);
    return;
  }
  fmt::print("beam {} (3 573 tets): CG {:.1f} iterations mean, mean {:.3f} ms per step\n",
             beam_mesh, r.beam_mean_cg_iterations, r.beam_mean_ms_per_step);
  fmt::print("beam_ms_per_step={:.3f}\n", r.beam_ms_per_step);
  fmt::print("beam_settled_error_pct={:.4f}\n", r.beam_settled_error_pct);
}

}  // namespace

void AddBenchCommand(CLI::App* app, int* exit_code) {
  auto* cmd = app->add_subcommand("bench", "Time the simulation (and rendering) on this machine");
  auto a = std::make_shared<BenchArgs>();
  cmd->add_option("scenario", a->scenario, "Scenario YAML file")->required();
  cmd->add_option("--steps", a->steps, "Timed steps")
      ->check(CLI::Range(1, 100000))
      ->capture_default_str();
  cmd->add_option("--trajectory", a->trajectory, "Input during the timed steps (default: idle)");
  cmd->add_option("--abusive", a->abusive,
                  "Abusive replay timed after the main figures (skipped if absent)")
      ->capture_default_str();
  cmd->add_option("--ops-dir", a->ops_dir,
                  "Directory of operation trajectories <instrument>.yaml timed one by one")
      ->capture_default_str();
  cmd->add_option("--beam-mesh", a->beam_mesh, "Cantilever mesh for the beam figures")
      ->capture_default_str();
  cmd->add_option("--threads", a->threads,
                  "Worker threads for the step and collision figures (wall time; results do not "
                  "depend on it); the soft-tissue suite always runs on one")
      ->check(CLI::Range(1, 64))
      ->capture_default_str();
  cmd->add_option("--trace", a->trace,
                  "Per-step CSV of the main figures' timed steps: wall ms of the step, its "
                  "stages (kinematics = tool proxies), factor work, CG iterations, contact "
                  "re-solves, contact and spring terms, factor switched in / requested, wall ms "
                  "and thread CPU ms of writing the step's frame (RunWriter::Append; flushes and "
                  "checkpoints included)");
  cmd->add_flag("--render", a->render, "Also measure rendering and encoding frame rates");
  cmd->callback([a, exit_code] {
    SetThreadCount(a->threads);
    const Model model = io::LoadScenario(a->scenario);
    fmt::print("bench_threads={}\n", a->threads);
    // closed however the timing ends (an input error mid-run included)
    std::unique_ptr<std::FILE, int (*)(std::FILE*)> trace(nullptr, &std::fclose);
    if (!a->trace.empty()) {
      trace.reset(std::fopen(a->trace.c_str(), "w"));
      if (!trace) throw InputError(a->trace, 0, "--trace", "cannot write this file");
      fmt::print(trace.get(),
                 "step,total_ms,kinematics_ms,collision_ms,rotations_ms,assembly_ms,factor_ms,"
                 "solve_ms,thread_ms,instruments_ms,cg_iterations,contact_resolves,active_terms,"
                 "refactored,factor_requested,thread_newton_iterations,thread_unconverged,"
                 "output_ms,output_cpu_ms\n");
    }
    PrintScenario(model, TimeScenario(model, a->trajectory, a->steps, -1, trace.get()), a->steps);
    trace.reset();
    PrintAbusive(model, a->abusive);
    PrintOperations(model, a->ops_dir);
    SetThreadCount(1);  // its figures are process CPU time
    PrintSoftSuite(model, a->beam_mesh);
    // Collision on the workload: a thread on the tendon, two instruments crossing it at
    // 100 mm/s (the stage alone: CPU time with one thread, wall time with more).
    SetThreadCount(a->threads);
    fmt::print("collision workload (thread on the tendon, grasper + shaver crossing it):\n{}",
               collision::FormatCollisionBench(collision::BenchmarkCollision(model, 300)));
    SetThreadCount(1);
    if (a->render) {
      setenv("LP_NUM_THREADS", "2", 0);
      fmt::print("{}", render::RenderBenchReport(model, render::MakeBenchmarkState(model), 100));
    }
    *exit_code = kExitOk;
  });
}

}  // namespace arthrosim::cli
