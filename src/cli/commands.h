#pragma once
// One function per subcommand. Each returns the process exit code:
// 0 ok, 1 a check failed (compare/score), 2 bad input or usage.
#include <CLI/CLI.hpp>

namespace arthrosim::cli {

inline constexpr int kExitOk = 0;
inline constexpr int kExitCheckFailed = 1;
inline constexpr int kExitBadInput = 2;

/// Registers the subcommand on app; the callback stores its exit code in *exit_code.
void AddRunCommand(CLI::App* app, int* exit_code);
void AddValidateCommand(CLI::App* app, int* exit_code);
void AddInfoCommand(CLI::App* app, int* exit_code);
void AddBenchCommand(CLI::App* app, int* exit_code);
void AddRenderCommand(CLI::App* app, int* exit_code);
void AddServeCommand(CLI::App* app, int* exit_code);
/// score and compare: reserved names until the scoring issue lands.
void AddReservedCommands(CLI::App* app, int* exit_code);

}  // namespace arthrosim::cli
