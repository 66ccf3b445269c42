#pragma once
// Where `arthrosim run` starts: t = 0 of a scenario, or a checkpoint of an earlier run file
// (`--resume RUN.h5`: its last checkpoint, the same input; `--from RUN.h5 --at T`: the
// checkpoint at or before T, the same or another input). docs/hdf5-layout.md, "Checkpoints".
#include <cstdint>
#include <optional>
#include <string>

#include "arthrosim/core/model.h"
#include "arthrosim/core/state.h"
#include "arthrosim/io/run_writer.h"

namespace arthrosim::cli {

/// What the command line asked for.
struct RunRequest {
  std::string scenario;    ///< SCENARIO ("" allowed with --resume / --from)
  std::string trajectory;  ///< --trajectory ("" = not given)
  std::optional<std::uint64_t> seed;
  std::optional<double> noise_scale;
  std::string resume;          ///< --resume RUN.h5
  std::string from;            ///< --from RUN.h5
  std::optional<double> at_s;  ///< --at T, s
  bool live = false;           ///< serve: input from a device
};

/// A run's starting point.
struct RunStart {
  Model model;
  State state;             ///< MakeInitialState(model), or the restored checkpoint
  bool restored = false;   ///< state comes from a checkpoint
  std::string trajectory;  ///< input spec to open ("none" = idle)
  std::optional<std::uint64_t> seed;
  double noise_scale = 0;
  /// Absolute step to run to, taken from the parent (--resume); -1 = from the arguments.
  std::int64_t end_step = -1;
  io::RunOrigin origin;     ///< input and parent, for the new run file
  std::string default_out;  ///< output when --out is not given ("" = the scenario's)
};

/// Loads the scenario (fresh run) or the checkpoint and its Model (--resume / --from), checking
/// that the run file fits this build, the scenario and the input. The input source's controllers
/// must then be restored from `state` (InputSource::RestoreControllers).
/// @throws InputError (exit 2) naming the file and what was expected: no checkpoint, T outside
///         the run, another scenario, another build, a changed trajectory, a live parent.
RunStart PrepareRunStart(const RunRequest& request);

/// For a restored start: refuses (InputError, exit 2) a continuation with no step left to run
/// (`steps` <= 0: the parent had finished; --steps / --duration run on) and an output file that
/// is the parent itself (the writer would truncate what it reads).
void CheckContinuation(const RunStart& start, const std::string& out, std::int64_t steps);

/// SHA-256 (hex) of a file's bytes, "" if it is not a readable regular file.
std::string FileSha256(const std::string& path);

/// Fault injection for crash tests: when the environment variable
/// ARTHROSIM_FAULT_KILL_AT_STEP is N >= 0, the process raises SIGKILL (or SIGINT / SIGTERM when
/// ARTHROSIM_FAULT_SIGNAL is INT / TERM) once step N has been handed to the writer (call after
/// each step's output). Does nothing otherwise.
void InjectKillAfterStep(std::int64_t step);

}  // namespace arthrosim::cli
