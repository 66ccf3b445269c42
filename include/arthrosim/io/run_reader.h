#pragma once
// RunReader: reads a run file written by RunWriter (docs/hdf5-layout.md), also while it is being
// written or after the writer was killed (SWMR read). Rebuilds the State of any frame; the
// per-frame index arrays are cached so that a frame costs a few hyperslab reads. HDF5 refuses to
// open one file for SWMR write and SWMR read in the same process: read a live run from another.
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "arthrosim/core/state.h"

namespace arthrosim::io {

/// Run-level facts (root attributes and /meta).
struct RunInfo {
  std::string scenario_name;
  std::string scenario_sha256;
  std::string scenario_path;           ///< as given to `run`
  std::string scenario_path_absolute;  ///< made absolute when written ("" in older files)
  std::string scenario_yaml;           ///< exact scenario text (to rebuild the Model)
  std::string arthrosim_version;
  double dt_s = 0;
  std::vector<std::string> soft_bodies, bones, threads, instruments;  ///< names, Model order
};

/// The scenario file whose directory the run's meshes are read relative to: the path as given to
/// `run` if it exists from the working directory, else the absolute path recorded when the run
/// was written (so `render`, `score` and `run --from` work from any directory).
/// @throws InputError (file = run_path, field "/meta scenario_path") if neither exists, naming
/// both and the remedy (--scenario FILE).
std::string LocateRunScenario(const std::string& run_path, const std::string& as_given,
                              const std::string& absolute);

class RunReader {
 public:
  /// Opens `path` read-only (SWMR read).
  /// @throws InputError (file = path) if it is missing or not an arthrosim run file.
  explicit RunReader(const std::string& path);
  ~RunReader();
  RunReader(RunReader&&) noexcept;
  RunReader& operator=(RunReader&&) noexcept;

  const RunInfo& info() const;
  /// Frames complete in the file (as of opening or the last Refresh()).
  std::int64_t frame_count() const;
  /// Picks up frames a live writer has flushed since (by reopening the file); returns the new
  /// frame count. @throws like the constructor; the reader is then unusable.
  std::int64_t Refresh();
  /// Simulated time (s) and step of frame k.
  double time(std::int64_t k) const;
  std::int64_t step(std::int64_t k) const;

  /// The State of frame k, reusing `out`'s buffers. Filled: step, time, positions and alive
  /// masks, tets (initial + appended), bone surfaces and removed volume, both tool slots, camera,
  /// constraints, tool contacts, rng_state, next_constraint_id, and the events recorded for frame k
  /// (those of the steps since frame k-1). Not stored, left empty: velocities, x_rest, dv_warm.
  /// @throws std::out_of_range if k is not in [0, frame_count()).
  void ReadFrame(std::int64_t k, State& out) const;
  State Frame(std::int64_t k) const;
  /// Every event recorded up to and including frame k, in order.
  std::vector<Event> EventsUpTo(std::int64_t k) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Text for `arthrosim info RUN.h5`: version, scenario, frames and duration, each body with node
/// and element counts and its bounding box at the last frame, bones, threads, tools, constraints
/// and event counts by kind.
std::string Summarize(const std::string& path);

}  // namespace arthrosim::io
