// arthrosim render RUN.h5 --video OUT.mp4 [--view scope|overview|both] [--size WxH] [--fps N]
//                  [--frames DIR] [--from S] [--to S] [--scenario FILE] [--plan PLAN]
// Renders a run file offline: States are read back from HDF5, never re-simulated. With --plan the
// overlay names the current step of the procedure plan, as scoring the run against it finds the
// steps' start and completion times.
#include <fmt/core.h>

#include <cmath>
#include <filesystem>
#include <utility>
#include <vector>

#include "arthrosim/core/error.h"
#include "arthrosim/io/run_reader.h"
#include "arthrosim/io/scenario_loader.h"
#include "arthrosim/scoring/plan.h"
#include "arthrosim/scoring/score.h"
#include "commands.h"
#include "video.h"

namespace arthrosim::cli {
namespace {

// The Model of a run: its stored scenario text, with meshes resolved next to the scenario path
// stored in the file (or the one given with --scenario).
Model RunModel(const io::RunReader& reader, const std::string& run,
               const std::string& override_path) {
  const io::RunInfo& info = reader.info();
  if (!override_path.empty()) {
    Model m = io::LoadScenario(override_path);
    if (m.scenario_sha256 != info.scenario_sha256) {
      fmt::print(stderr, "warning: {} differs from the scenario stored in {}\n", override_path,
                 run);
    }
    return m;
  }
  return io::LoadScenarioFromText(
      info.scenario_yaml,
      io::LocateRunScenario(run, info.scenario_path, info.scenario_path_absolute));
}

// The plan's steps with their times in `run` (scoring the run against the plan).
std::vector<render::StepSpan> PlanSteps(const std::string& run, const std::string& plan_path,
                                        const Model& model) {
  const scoring::Plan plan = scoring::LoadPlan(plan_path, &model);
  const scoring::ScoreReport report = scoring::Evaluate(plan, scoring::ReadRunData(run, model));
  std::vector<render::StepSpan> steps;
  for (const scoring::StepResult& s : report.steps) {
    steps.push_back({s.title, s.start_s, s.completed ? s.end_s : NAN});
  }
  return steps;
}

}  // namespace

void AddRenderCommand(CLI::App* app, int* exit_code) {
  auto* cmd = app->add_subcommand("render", "Render a run file to MP4 video or PNG frames");
  auto run = std::make_shared<std::string>();
  auto scenario = std::make_shared<std::string>();
  auto args = std::make_shared<VideoArgs>();
  auto plan = std::make_shared<std::string>();
  cmd->add_option("run", *run, "Run file (.h5) written by arthrosim run")->required();
  cmd->add_option("--video", args->video, "Output MP4 file");
  cmd->add_option("--scenario", *scenario, "Scenario file if the run's is not at its stored path");
  cmd->add_option("--plan", *plan,
                  "Procedure plan: the overlay names the current step (docs/plan-format.md)");
  AddVideoOptions(cmd, args.get(), false);
  cmd->callback([run, scenario, plan, args, exit_code] {
    if (args->video.empty() && args->frames_dir.empty()) {
      throw InputError("", 0, "--video", "give --video OUT.mp4 or --frames DIR");
    }
    io::RunReader reader(*run);
    const Model model = RunModel(reader, *run, *scenario);
    render::OverlayTextFn overlay;
    if (!plan->empty()) {
      overlay = [steps = PlanSteps(*run, *plan, model)](const State& s, render::Overlay* o) {
        render::StepOverlayText(steps, s.time_s, o);
      };
    }
    VideoOutput video(model, *args, std::move(overlay));
    State state;
    for (std::int64_t k = 0; k < reader.frame_count(); ++k) {
      reader.ReadFrame(k, state);
      video.Push(state);
    }
    video.Finish();
    fmt::print(stderr, "{}: {} frames\n", args->video.empty() ? args->frames_dir : args->video,
               video.frames());
    *exit_code = kExitOk;
  });
}

}  // namespace arthrosim::cli
