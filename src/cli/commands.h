#pragma once
// One function per subcommand. Each returns the process exit code:
// 0 ok, 1 a check failed (compare/score), 2 bad input or usage, 3 the simulation could not
// continue (a step diverged even in substeps: sim::SimulationError), 130 interrupted.
#include <CLI/CLI.hpp>

namespace arthrosim::cli {

inline constexpr int kExitOk = 0;
inline constexpr int kExitCheckFailed = 1;
inline constexpr int kExitBadInput = 2;
inline constexpr int kExitSimulationFailed = 3;

/// Registers the subcommand on app; the callback stores its exit code in *exit_code.
void AddRunCommand(CLI::App* app, int* exit_code);
void AddValidateCommand(CLI::App* app, int* exit_code);
void AddInfoCommand(CLI::App* app, int* exit_code);
void AddBenchCommand(CLI::App* app, int* exit_code);
void AddRenderCommand(CLI::App* app, int* exit_code);
void AddServeCommand(CLI::App* app, int* exit_code);
/// score: a run against a procedure plan (exit 0 pass, 1 fail, 2 bad input).
void AddScoreCommand(CLI::App* app, int* exit_code);
/// compare: a run against a golden file (exit 0 equal, 1 regression, 2 bad input).
void AddCompareCommand(CLI::App* app, int* exit_code);

}  // namespace arthrosim::cli
