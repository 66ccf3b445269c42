// arthrosim run SCENARIO [--trajectory F] [--out F.h5] [--duration S | --steps N] [--threads N]
// Loads the scenario, replays the trajectory through the fixed-step core and writes HDF5.
#include <fmt/core.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <csignal>
#include <limits>
#include <memory>
#include <optional>

#include "arthrosim/core/error.h"
#include "arthrosim/core/parallel.h"
#include "arthrosim/input/open_source.h"
#include "arthrosim/io/run_writer.h"
#include "arthrosim/io/scenario_loader.h"
#include "arthrosim/sim/step.h"
#include "commands.h"
#include "progress.h"
#include "video.h"

namespace arthrosim::cli {
namespace {

std::atomic<bool> g_interrupted{false};
void OnSignal(int) { g_interrupted = true; }

struct RunArgs {
  std::string scenario, trajectory, out, record;
  double duration_s = -1;
  std::int64_t steps = -1;
  int threads = 1;
  bool quiet = false;
  std::optional<std::uint64_t> seed;
  double noise_scale = 0;
  bool live = false;       // serve: input from a device, paced to real time, runs until it ends
  double max_force_n = 0;  // serve --max-force: overrides haptics.max_force_n when > 0
  VideoArgs video;
};

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

int Run(const RunArgs& a) {
  SetThreadCount(a.threads);
  Model loaded = io::LoadScenario(a.scenario);
  if (a.max_force_n > 0) loaded.haptics.max_force_n = a.max_force_n;
  const Model model = std::move(loaded);
  input::SourceOptions options;
  options.dt_s = model.options.dt_s;
  options.seed = a.seed;
  options.noise_scale = a.noise_scale;
  options.record_path = a.record;
  std::vector<std::string> warnings;
  std::unique_ptr<input::InputSource> source = input::OpenInputSource(
      a.trajectory.empty() ? "none" : a.trajectory, model, options, &warnings);
  for (const std::string& w : warnings) fmt::print(stderr, "warning: {}\n", w);
  const std::int64_t steps = StepCount(a, model, source.get());
  const std::string out = a.out.empty() ? model.options.output_file : a.out;

  State state = MakeInitialState(model);
  sim::Workspace ws;
  sim::BuildWorkspace(model, state, &ws);
  io::RunWriter writer(out, model, state);
  std::unique_ptr<VideoOutput> video;
  if (!a.video.video.empty() || !a.video.frames_dir.empty()) {
    video = std::make_unique<VideoOutput>(model, a.video);
    video->Push(state);
  }

  std::signal(SIGINT, OnSignal);
  std::signal(SIGTERM, OnSignal);
  ProgressBar bar(steps, !a.quiet && !a.live);
  InputFrame frame;
  const int every = model.options.output_every_steps;
  LagReporter lag;
  lag.threshold_s = std::max(lag.threshold_s, 5 * model.options.dt_s);
  for (std::int64_t k = 0; k < steps && !g_interrupted; ++k) {
    if (a.live && source->Finished(state.time_s)) break;
    source->Frame(state.step + 1, static_cast<double>(state.step + 1) * model.options.dt_s, &frame);
    sim::Step(model, frame, &state, &ws);
    source->Feedback(sim::Feedback(state));
    if (a.live) lag.Check(source->RealtimeLagS(), &state);
    if (state.step % every == 0) {
      writer.Append(state);
      if (video) video->Push(state);
    } else {
      writer.RecordEvents(state);
    }
    bar.Update(k + 1);
  }
  bar.Finish();
  writer.Close();
  if (a.live && lag.max_s > 0) {
    fmt::print(stderr, "serve: largest lag behind real time {:.3f} s ({} reports)\n", lag.max_s,
               lag.reports);
  }
  if (video) video->Finish();
  if (g_interrupted) {
    fmt::print(stderr, "interrupted at step {}: {} holds {} frames\n", state.step, out,
               writer.frames());
    return 130;
  }
  if (!a.quiet) {
    fmt::print(stderr, "{}: {} steps ({:.2f} s simulated), {} frames\n", out, state.step,
               state.time_s, writer.frames());
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
  cmd->add_flag("--quiet", a->quiet, "No progress bar or summary");
  cmd->callback([a, bind, port, exit_code] {
    a->live = true;
    a->trajectory = "igtl:" + *bind + ":" + std::to_string(*port);
    *exit_code = Run(*a);
  });
}

void AddRunCommand(CLI::App* app, int* exit_code) {
  auto* cmd = app->add_subcommand("run", "Run a scenario with a trajectory and write HDF5");
  auto a = std::make_shared<RunArgs>();
  cmd->add_option("scenario", a->scenario, "Scenario YAML file")->required();
  cmd->add_option("--trajectory", a->trajectory,
                  "Recorded session (.csv, .h5), synthetic script (.yaml), or igtl[:ADDR][:PORT] "
                  "for a live device; default: idle");
  cmd->add_option("--seed", a->seed, "Seed of the script noise model (default: the script's)");
  cmd->add_option(
         "--noise-scale", a->noise_scale,
         "Trainee noise of a script: 0 = the expert script as written, 1 = its noise block")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--record", a->record, "Record the applied input per step as a session CSV");
  cmd->add_option("--out", a->out, "HDF5 output file (default: the scenario's output.file)");
  auto* duration = cmd->add_option("--duration", a->duration_s, "Simulated seconds to run")
                       ->check(CLI::PositiveNumber);
  auto* steps =
      cmd->add_option("--steps", a->steps, "Number of steps to run")->check(CLI::NonNegativeNumber);
  duration->excludes(steps);
  cmd->add_option("--threads", a->threads, "Worker threads (results do not depend on it)")
      ->check(CLI::Range(1, 256));
  cmd->add_flag("--quiet", a->quiet, "No progress bar or summary");
  AddVideoOptions(cmd, &a->video, true);
  cmd->callback([a, exit_code] { *exit_code = Run(*a); });
}

}  // namespace arthrosim::cli
