// arthrosim run SCENARIO [--trajectory F] [--out F.h5] [--duration S | --steps N] [--threads N]
//              [--resume RUN.h5 | --from RUN.h5 --at T] [--igtl-device NAME=TARGET ...]
// Loads the scenario (or a run file's checkpoint), replays the trajectory through the fixed-step
// core and writes HDF5.
#include <fmt/core.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <csignal>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "arthrosim/core/error.h"
#include "arthrosim/core/parallel.h"
#include "arthrosim/input/open_source.h"
#include "arthrosim/io/run_writer.h"
#include "arthrosim/io/scenario_loader.h"
#include "arthrosim/sim/step.h"
#include "arthrosim/sim/tool_proxy.h"
#include "commands.h"
#include "live_feedback.h"
#include "progress.h"
#include "run_resume.h"
#include "video.h"

namespace arthrosim::cli {
namespace {

std::atomic<bool> g_interrupted{false};
void OnSignal(int) { g_interrupted = true; }

struct RunArgs {
  std::string scenario, trajectory, out, record;
  std::string plan;  // --plan: live feedback against this procedure plan (live_feedback.h)
  double duration_s = -1;
  std::int64_t steps = -1;
  int threads = 1;
  bool quiet = false;
  std::optional<std::uint64_t> seed;
  double noise_scale = 0;
  bool live = false;       // serve: input from a device, paced to real time, runs until it ends
  double max_force_n = 0;  // serve --max-force: overrides haptics.max_force_n when > 0
  VideoArgs video;
  std::string resume, from;               // --resume RUN.h5, --from RUN.h5 (run_resume.h)
  std::optional<double> at_s;             // --at T
  std::vector<std::string> igtl_devices;  // --igtl-device NAME=TARGET (live input only)
};

// The --igtl-device mappings, checked before anything is loaded; live input only.
input::IgtlDeviceNames DeviceNames(const RunArgs& a) {
  input::IgtlDeviceNames names;
  for (const std::string& spec : a.igtl_devices) input::AddIgtlDeviceName(spec, &names);
  if (!names.empty() && a.trajectory != "igtl" && a.trajectory.rfind("igtl:", 0) != 0) {
    throw InputError("--igtl-device", 0, "",
                     "maps live device names; it needs --trajectory igtl[:ADDR][:PORT] (or serve)");
  }
  return names;
}

// --igtl-device on `run` and `serve`.
void AddDeviceNameOption(CLI::App* cmd, RunArgs* a) {
  cmd->add_option("--igtl-device", a->igtl_devices,
                  "Map a device's own TRANSFORM name to a slot: NAME=slot0|slot1|scope|ignore "
                  "(repeatable; e.g. StylusToTracker=slot0; docs/haptics.md)");
}

// Live runs say when they fall behind real time: a log line and a `realtime_lag` event (detail
// lag_s=<seconds>) when the lag first exceeds the threshold and each time it grows by another
// second; a summary of the largest lag at the end.
struct LagReporter {
  double threshold_s = 0.1;
  double reported_s = 0;  // lag at the last report; 0 = on time since
  double max_s = 0;
  int reports = 0;
  void Check(double lag_s, State* state) {
    max_s = std::max(max_s, lag_s);
    if (lag_s < threshold_s) {
      reported_s = 0;
      return;
    }
    if (reported_s > 0 && lag_s < reported_s + 1.0) return;
    reported_s = lag_s;
    ++reports;
    fmt::print(stderr, "serve: {:.3f} s behind real time at t = {:.3f} s (step {})\n", lag_s,
               state->time_s, state->step);
    state->events.push_back(Event{state->step, state->time_s, "realtime_lag", "", "",
                                  fmt::format("lag_s={:.6f}", lag_s), Vec3::Zero()});
  }
};

// Number of steps: --steps, else --duration, else the trajectory's length, else the scenario's.
std::int64_t StepCount(const RunArgs& a, const Model& m, const input::InputSource* source) {
  if (a.steps >= 0) return a.steps;
  double duration = m.options.duration_s;
  if (a.duration_s >= 0) {
    duration = a.duration_s;
  } else if (a.live) {
    return std::numeric_limits<std::int64_t>::max();  // until the device ends the session
  } else if (!a.trajectory.empty()) {
    // Step k applies the input at t = (k + 1) dt: run while that time still has input, so the
    // last step applies the last sample (bounded by one hour of simulated time).
    std::int64_t n = 0;
    while (!source->Finished(static_cast<double>(n + 1) * m.options.dt_s) && n < 180000) ++n;
    return n;
  }
  return static_cast<std::int64_t>(std::llround(duration / m.options.dt_s));
}

RunStart Start(const RunArgs& a) {
  RunRequest r{a.scenario, a.trajectory, a.seed, std::nullopt, a.resume, a.from, a.at_s, a.live};
  if (a.noise_scale > 0) r.noise_scale = a.noise_scale;
  return PrepareRunStart(r);
}

int Run(const RunArgs& a) {
  // From the start: an interrupt while loading stops before any file is made, one later stops
  // the run at the end of a step with a closed file and a last checkpoint.
  std::signal(SIGINT, OnSignal);
  std::signal(SIGTERM, OnSignal);
  input::IgtlDeviceNames device_names = DeviceNames(a);
  SetThreadCount(a.threads);
  RunStart start = Start(a);
  if (a.max_force_n > 0) start.model.haptics.max_force_n = a.max_force_n;
  const Model model = std::move(start.model);
  std::unique_ptr<LiveFeedback> feedback;  // the plan is checked before anything is opened
  if (!a.plan.empty()) feedback = std::make_unique<LiveFeedback>(a.plan, model, !a.quiet);
  input::SourceOptions options;
  options.dt_s = model.options.dt_s;
  options.seed = start.seed;
  options.noise_scale = start.noise_scale;
  options.record_path = a.record;
  options.igtl_devices = std::move(device_names);
  std::vector<std::string> warnings;
  std::unique_ptr<input::InputSource> source =
      input::OpenInputSource(start.trajectory, model, options, &warnings);
  for (const std::string& w : warnings) fmt::print(stderr, "warning: {}\n", w);
  State state = std::move(start.state);
  if (start.restored) source->RestoreControllers(state);
  std::int64_t steps = StepCount(a, model, source.get());
  if (start.restored && a.steps < 0 && a.duration_s < 0) {  // to the parent's (absolute) end
    steps = (start.end_step >= 0 ? start.end_step : steps) - state.step;
  }
  const std::string out =
      !a.out.empty() ? a.out
                     : (start.default_out.empty() ? model.options.output_file : start.default_out);
  CheckContinuation(start, out, steps);
  if (g_interrupted) {
    fmt::print(stderr, "interrupted before the run started: no output written\n");
    return 130;
  }

  sim::Workspace ws;
  sim::BuildWorkspace(model, state, &ws);
  io::RunWriterOptions writer_options;
  writer_options.origin = start.origin;
  writer_options.origin.end_step = a.live ? -1 : state.step + steps;
  io::RunWriter writer(out, model, state, writer_options);
  std::unique_ptr<VideoOutput> video;
  if (!a.video.video.empty() || !a.video.frames_dir.empty()) {
    video = std::make_unique<VideoOutput>(model, a.video);
    video->Push(state);
  }

  if (feedback) feedback->Begin(state, source.get());

  ProgressBar bar(steps, !a.quiet && !a.live);
  InputFrame frame;
  const int every = model.options.output_every_steps;
  LagReporter lag;
  lag.threshold_s = std::max(lag.threshold_s, 5 * model.options.dt_s);
  // Wall time is printed only (the real-time factor), never written into results.
  const auto wall_start = std::chrono::steady_clock::now();
  const double start_time_s = state.time_s;  // a continued run starts at its checkpoint's time
  // Thread solves that stopped before converging (max_newton_iterations or the line-search
  // floor), counted from each step's last thread solve; printed only (docs/operations.md).
  std::int64_t thread_solves = 0, thread_unconverged = 0, thread_substeps = 0;
  // The tool proxy's work (docs/contact-model.md): clearance searches and slot-steps that ran
  // into the iteration cap; printed only.
  std::int64_t proxy_queries = 0, proxy_capped = 0, proxy_reused = 0, proxy_cycles = 0;
  for (std::int64_t k = 0; k < steps && !g_interrupted; ++k) {
    if (a.live && source->Finished(state.time_s)) break;
    source->Frame(state.step + 1, static_cast<double>(state.step + 1) * model.options.dt_s, &frame);
    source->SaveControllers(&state);
    try {
      sim::Step(model, frame, &state, &ws);
    } catch (const sim::SimulationError& e) {
      // The step cannot be solved: what was written stays (frames and checkpoints up to the
      // last step), closed; no checkpoint of the half-done step.
      bar.Finish();
      writer.Close();
      if (video) video->Finish();
      fmt::print(stderr, "error: {}\n{} holds {} frames up to step {}\n", e.what(), out,
                 writer.frames(), e.step() - 1);
      return kExitSimulationFailed;
    }
    thread_solves += ws.timings.thread.solves;
    thread_unconverged += ws.timings.thread.unconverged_solves;
    proxy_queries += ws.proxy.clearance_queries;
    proxy_reused += ws.proxy.reused;
    proxy_cycles += ws.proxy.cycles;
    for (int it : ws.proxy.iterations) proxy_capped += it >= sim::kProxyMaxIterations ? 1 : 0;
    thread_substeps += ws.timings.thread.substeps;
    source->Feedback(sim::Feedback(state));
    if (a.live) lag.Check(source->RealtimeLagS(), &state);
    if (feedback) feedback->AfterStep(state.step % every == 0, &state, source.get());
    if (state.step % every == 0) {
      writer.Append(state);
      if (video) video->Push(state);
    } else {
      writer.RecordEvents(state);
    }
    InjectKillAfterStep(state.step);
    bar.Update(k + 1);
  }
  bar.Finish();
  writer.WriteCheckpoint(state);  // the last state, also of an interrupted run
  const double wall_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start).count();
  writer.Close();
  if (a.live && lag.max_s > 0) {
    fmt::print(stderr, "serve: largest lag behind real time {:.3f} s ({} reports)\n", lag.max_s,
               lag.reports);
  }
  if (video) video->Finish();
  if (feedback) feedback->Finish();
  if (g_interrupted) {
    fmt::print(stderr,
               "interrupted at step {}: {} holds {} frames and a checkpoint of this step "
               "(continue with: arthrosim run --resume {})\n",
               state.step, out, writer.frames(), out);
    return 130;
  }
  if (!a.quiet) {
    fmt::print(stderr, "{}: {} steps ({:.2f} s simulated), {} frames\n", out, state.step,
               state.time_s, writer.frames());
    // the step loop only (stepping, writing, live video); real-time factor = simulated / wall
    fmt::print(stderr, "wall time {:.2f} s, real-time factor {:.2f}x\n", wall_s,
               wall_s > 0 ? (state.time_s - start_time_s) / wall_s : 0.0);
    fmt::print(stderr,
               "thread solves unconverged: {} of {} (thread_solver.max_newton_iterations {})\n",
               thread_unconverged, thread_solves, model.thread_solver.max_newton_iterations);
    fmt::print(stderr,
               "tool proxy: {} clearance queries, {} slot-steps at the {}-iteration cap ({} "
               "ended by a repeated state), {} taken from the step before (same inputs)\n",
               proxy_queries, proxy_capped, sim::kProxyMaxIterations, proxy_cycles, proxy_reused);
    if (model.thread_solver.max_substep_levels > 0) {
      fmt::print(stderr, "thread substeps: {} (thread_solver.max_substep_levels {})\n",
                 thread_substeps, model.thread_solver.max_substep_levels);
    }
  }
  return kExitOk;
}

}  // namespace

void AddServeCommand(CLI::App* app, int* exit_code) {
  auto* cmd = app->add_subcommand(
      "serve",
      "Run a scenario live from an OpenIGTLink device, paced to real time (docs/haptics.md)");
  auto a = std::make_shared<RunArgs>();
  auto bind = std::make_shared<std::string>("127.0.0.1");
  auto port = std::make_shared<int>(18944);
  cmd->add_option("scenario", a->scenario, "Scenario YAML file")->required();
  cmd->add_option("--bind", *bind, "Address to listen on (default loopback only)");
  cmd->add_option("--port", *port, "TCP port (OpenIGTLink default 18944)")
      ->check(CLI::Range(1, 65535));
  cmd->add_option("--record", a->record, "Record the received stream as a session CSV");
  cmd->add_option("--out", a->out, "HDF5 output file (default: the scenario's output.file)");
  cmd->add_option("--duration", a->duration_s, "Stop after this many simulated seconds")
      ->check(CLI::PositiveNumber);
  cmd->add_option("--max-force", a->max_force_n,
                  "Clamp of the force sent to the device, N (default: the scenario's "
                  "haptics.max_force_n; docs/haptics.md lists device values)")
      ->check(CLI::PositiveNumber);
  cmd->add_option("--plan", a->plan,
                  "Procedure plan: warn the trainee live (STRING messages, live_warning events; "
                  "docs/metrics.md)");
  cmd->add_flag("--quiet", a->quiet, "No progress bar or summary");
  AddDeviceNameOption(cmd, a.get());
  cmd->callback([a, bind, port, exit_code] {
    a->live = true;
    a->trajectory = "igtl:" + *bind + ":" + std::to_string(*port);
    *exit_code = Run(*a);
  });
}

void AddRunCommand(CLI::App* app, int* exit_code) {
  auto* cmd = app->add_subcommand("run", "Run a scenario with a trajectory and write HDF5");
  auto a = std::make_shared<RunArgs>();
  cmd->add_option("scenario", a->scenario,
                  "Scenario YAML file (optional with --resume / --from: the run file's own)");
  cmd->add_option("--trajectory", a->trajectory,
                  "Recorded session (.csv, .h5), synthetic script (.yaml), or igtl[:ADDR][:PORT] "
                  "for a live device; default: idle");
  cmd->add_option("--seed", a->seed, "Seed of the script noise model (default: the script's)");
  cmd->add_option(
         "--noise-scale", a->noise_scale,
         "Trainee noise of a script: 0 = the expert script as written, 1 = its noise block")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--record", a->record, "Record the applied input per step as a session CSV");
  cmd->add_option("--plan", a->plan,
                  "Procedure plan: live_warning events as `serve --plan` gives (docs/metrics.md)");
  cmd->add_option("--out", a->out, "HDF5 output file (default: the scenario's output.file)");
  auto* duration = cmd->add_option("--duration", a->duration_s, "Simulated seconds to run")
                       ->check(CLI::PositiveNumber);
  auto* steps =
      cmd->add_option("--steps", a->steps, "Number of steps to run")->check(CLI::NonNegativeNumber);
  duration->excludes(steps);
  cmd->add_option("--threads", a->threads, "Worker threads (results do not depend on it)")
      ->check(CLI::Range(1, 256));
  cmd->add_flag("--quiet", a->quiet, "No progress bar or summary");
  AddDeviceNameOption(cmd, a.get());
  AddVideoOptions(cmd, &a->video, true);
  // A run's video covers the run: `render`'s time range (--from S --to S) does not apply here,
  // and --from names the run file to start from.
  cmd->remove_option(cmd->get_option("--from"));
  cmd->remove_option(cmd->get_option("--to"));
  auto* resume = cmd->add_option("--resume", a->resume,
                                 "Continue a killed or finished run from its last checkpoint, with "
                                 "its own input, into a new file (default RUN.resumed.h5)");
  auto* from = cmd->add_option("--from", a->from,
                               "Start a new run from a run file's checkpoint at or before --at");
  auto* at = cmd->add_option("--at", a->at_s, "Simulated time (s) of the --from checkpoint")
                 ->check(CLI::NonNegativeNumber);
  resume->excludes(from);
  at->needs(from);
  cmd->callback([a, exit_code] {
    // Live input is live whichever command reads it: paced to real time, until the device
    // ends the session (it ran 180 000 steps past the session's end before).
    if (a->trajectory == "igtl" || a->trajectory.rfind("igtl:", 0) == 0) a->live = true;
    *exit_code = Run(*a);
  });
}

}  // namespace arthrosim::cli
