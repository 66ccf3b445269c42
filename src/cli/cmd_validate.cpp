// arthrosim validate SCENARIO: load and check a scenario without running it.
#include <fmt/core.h>

#include "arthrosim/io/scenario_loader.h"
#include "commands.h"

namespace arthrosim::cli {

void AddValidateCommand(CLI::App* app, int* exit_code) {
  auto* cmd =
      app->add_subcommand("validate", "Check a scenario file (and its meshes) without running it");
  auto path = std::make_shared<std::string>();
  cmd->add_option("scenario", *path, "Scenario YAML file")->required();
  cmd->callback([path, exit_code] {
    const Model model = io::LoadScenario(*path);
    std::size_t tets = 0;
    for (const auto& b : model.soft_bodies) tets += b.rest_mesh.tets.size();
    fmt::print("{}: ok ({} soft bodies, {} tets, {} bones, {} threads, {} instruments, dt {} s)\n",
               *path, model.soft_bodies.size(), tets, model.bones.size(), model.threads.size(),
               model.instruments.size(), model.options.dt_s);
    *exit_code = kExitOk;
  });
}

}  // namespace arthrosim::cli
