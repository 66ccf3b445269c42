// Subcommands whose names are reserved for issues that have not landed yet. They say so
// plainly and exit with 2 rather than pretend to work.
#include <fmt/core.h>

#include "commands.h"

namespace arthrosim::cli {

void AddReservedCommands(CLI::App* app, int* exit_code) {
  for (const char* name : {"score", "compare"}) {
    auto* cmd = app->add_subcommand(name, std::string("(reserved: not implemented yet)"));
    cmd->allow_extras();
    cmd->callback([name, exit_code] {
      fmt::print(stderr, "arthrosim {}: not implemented yet\n", name);
      *exit_code = kExitBadInput;
    });
  }
}

}  // namespace arthrosim::cli
