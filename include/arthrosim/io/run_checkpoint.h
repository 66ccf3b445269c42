#pragma once
// Reading the checkpoints of a run file (/checkpoints, docs/hdf5-layout.md): full, exact States
// written by RunWriter every Model::options.checkpoint_every_s and at the end of a run, from
// which `arthrosim run --resume` / `--from RUN --at T` continue bit for bit.
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "arthrosim/core/model.h"
#include "arthrosim/core/state.h"
#include "arthrosim/io/run_writer.h"

namespace arthrosim::io {

/// One complete checkpoint of a run file.
struct CheckpointEntry {
  std::int64_t step = 0;
  double time_s = 0;
  std::int64_t frame = -1;       ///< frame written at the same step, -1 if none
  std::uint64_t state_hash = 0;  ///< HashState of the checkpointed State
  std::int64_t bytes = 0;        ///< size of its encoding (before deflate)
};

/// The build that wrote a run file (root and /meta attributes).
struct RunBuild {
  std::string arthrosim_version, compiler, cxx_flags, build_type;
  std::string state_layout;  ///< StateLayoutSignature() as 16 hex digits ("" = no checkpoints)
};

class RunCheckpoints {
 public:
  /// Opens `path` read-only (SWMR read: also a killed or live run) and lists its complete
  /// checkpoints. @throws InputError (file = path) if it is missing or not a run file.
  explicit RunCheckpoints(const std::string& path);
  ~RunCheckpoints();
  RunCheckpoints(RunCheckpoints&&) noexcept;
  RunCheckpoints& operator=(RunCheckpoints&&) noexcept;

  const std::string& path() const;
  /// Complete checkpoints in step order (empty for files written without checkpoints).
  const std::vector<CheckpointEntry>& entries() const;
  /// The run's origin: its input, the step it was asked to reach, its parent (/meta attributes).
  const RunOrigin& origin() const;
  const RunBuild& build() const;
  /// The exact scenario text, its path as given and its SHA-256 (/meta, root attribute).
  const std::string& scenario_yaml() const;
  const std::string& scenario_path() const;
  /// The scenario's path made absolute when the run was written ("" in older files).
  const std::string& scenario_path_absolute() const;
  const std::string& scenario_sha256() const;
  double dt_s() const;

  /// "" when this build can continue the file's checkpoints (same version, compiler, flags,
  /// build type and State layout); otherwise what differs, e.g. "compiler 'GNU 12.2.0' (this
  /// build: 'Clang 14.0.6')".
  std::string BuildMismatch() const;
  /// The index of the last checkpoint at or before simulated time t_s (s), -1 if none.
  std::int64_t AtOrBefore(double t_s) const;
  /// Decodes checkpoint i (relative to MakeInitialState(model); `model` must be the file's
  /// scenario) and checks it against its recorded hash.
  /// @throws InputError (file = path, field checkpoints) if the bytes are damaged or do not
  ///         decode to the recorded State; std::out_of_range for a bad index.
  State Read(std::size_t i, const Model& model) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// StateLayoutSignature() as 16 lower-case hex digits.
std::string StateLayoutHex();
/// This build's RunBuild (what RunWriter stores).
RunBuild CurrentBuild();

}  // namespace arthrosim::io
