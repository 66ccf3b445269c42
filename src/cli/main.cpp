// arthrosim: command-line entry point. Subcommands live in cmd_*.cpp.
#include <fmt/core.h>

#include <cstdio>

#include "arthrosim/core/error.h"
#include "arthrosim/sim/solve_guard.h"
#include "commands.h"

int main(int argc, char** argv) {
  using namespace arthrosim::cli;
  CLI::App app{"arthrosim: deterministic rotator-cuff arthroscopy simulator"};
  app.require_subcommand(1);
  int exit_code = kExitOk;
  AddRunCommand(&app, &exit_code);
  AddValidateCommand(&app, &exit_code);
  AddInfoCommand(&app, &exit_code);
  AddServeCommand(&app, &exit_code);
  AddRenderCommand(&app, &exit_code);
  AddBenchCommand(&app, &exit_code);
  AddScoreCommand(&app, &exit_code);
  AddCompareCommand(&app, &exit_code);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? kExitOk : kExitBadInput;
  } catch (const arthrosim::sim::SimulationError& e) {
    fmt::print(stderr, "error: {}\n", e.what());
    return kExitSimulationFailed;
  } catch (const arthrosim::InputError& e) {
    fmt::print(stderr, "error: {}\n", e.what());
    return kExitBadInput;
  } catch (const std::exception& e) {
    fmt::print(stderr, "error: {}\n", e.what());
    return kExitBadInput;
  }
  return exit_code;
}
