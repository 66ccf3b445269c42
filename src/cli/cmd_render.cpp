// arthrosim render RUN.h5 --video OUT.mp4 [--view scope|overview|both] [--size WxH] [--fps N]
//                  [--frames DIR] [--from S] [--to S] [--scenario FILE]
// Renders a run file offline: States are read back from HDF5, never re-simulated.
#include <fmt/core.h>

#include <filesystem>

#include "arthrosim/core/error.h"
#include "arthrosim/io/run_reader.h"
#include "arthrosim/io/scenario_loader.h"
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
  if (!std::filesystem::exists(info.scenario_path)) {
    throw InputError(run, 0, "/meta scenario_path",
                     "the run's scenario '" + info.scenario_path +
                         "' is not here (its meshes are needed); pass --scenario FILE");
  }
  return io::LoadScenarioFromText(info.scenario_yaml, info.scenario_path);
}

}  // namespace

void AddRenderCommand(CLI::App* app, int* exit_code) {
  auto* cmd = app->add_subcommand("render", "Render a run file to MP4 video or PNG frames");
  auto run = std::make_shared<std::string>();
  auto scenario = std::make_shared<std::string>();
  auto args = std::make_shared<VideoArgs>();
  cmd->add_option("run", *run, "Run file (.h5) written by arthrosim run")->required();
  cmd->add_option("--video", args->video, "Output MP4 file");
  cmd->add_option("--scenario", *scenario, "Scenario file if the run's is not at its stored path");
  AddVideoOptions(cmd, args.get(), false);
  cmd->callback([run, scenario, args, exit_code] {
    if (args->video.empty() && args->frames_dir.empty()) {
      throw InputError("", 0, "--video", "give --video OUT.mp4 or --frames DIR");
    }
    io::RunReader reader(*run);
    const Model model = RunModel(reader, *run, *scenario);
    VideoOutput video(model, *args);
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
