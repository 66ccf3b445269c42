#pragma once
// RunWriter: the run's HDF5 output (layout in docs/hdf5-layout.md). The whole layout is created
// up front, then the file switches to SWMR so that a killed run leaves a file readable (h5py with
// swmr=True, RunReader) up to at least the last flush. Frames are buffered in memory and appended
// in blocks to fixed extensible datasets; what changes rarely (alive tets, bone surfaces,
// constraints) is written as blocks only when it changed, with per-frame offset/count arrays. A
// run.xmf sidecar for ParaView is rewritten atomically at every flush and at Close().
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>

#include "arthrosim/core/model.h"
#include "arthrosim/core/state.h"
#include "arthrosim/io/xdmf.h"

namespace arthrosim::io {

/// Where a run comes from, stored as /meta attributes (docs/hdf5-layout.md): the input that
/// drives it, so that `run --resume` can reopen it, and for a run started from another run's
/// checkpoint (`run --resume`, `run --from`), that parent.
struct RunOrigin {
  std::string trajectory = "none";      ///< input spec as given: none, a file, igtl[:...]
  std::string trajectory_sha256;        ///< SHA-256 of the trajectory file ("" if not a file)
  std::int64_t noise_seed = -1;         ///< script noise seed given on the command line (-1: none)
  double noise_scale = 0;               ///< script trainee-noise scale
  std::int64_t end_step = -1;           ///< the step the run was asked to reach (-1: open-ended)
  std::string parent;                   ///< run file this run continues ("" = it starts at t = 0)
  std::int64_t parent_step = -1;        ///< step of the parent's checkpoint it starts from
  double parent_time_s = 0;             ///< simulated time of that checkpoint, s
  std::uint64_t parent_state_hash = 0;  ///< HashState of that checkpoint
};

struct RunWriterOptions {
  /// zlib level 0..9 (with byte shuffle) for integer, mask, index, record and small float
  /// datasets: they shrink many-fold at little cost.
  int deflate_level = 4;
  /// zlib level (with byte shuffle) for the bulk coordinates (positions, bone vertices). The
  /// quantised positions' low mantissa bytes are zero and unmoved nodes repeat the previous
  /// block's bytes, so they shrink ~10-fold; level 6 stores them in 13 % less than 4 for 1.5x
  /// the time (~1.7 ms per 64 KiB chunk, compressed as each chunk fills).
  int float_deflate_level = 6;
  /// Soft-body and thread node positions are stored rounded to multiples of this (a power of
  /// two, mm; 2^-10 mm ~ 0.98 um), 0 = exact.
  double position_quantum_mm = 1.0 / 1024.0;
  /// A stored node keeps its value while none of its coordinates moved more than this (mm) from
  /// it; a body's positions block is stored again only when a node changed. Every stored
  /// coordinate is within max(position_tolerance_mm, position_quantum_mm / 2) of the State's.
  /// 0 with position_quantum_mm 0: positions read back bit-identical.
  double position_tolerance_mm = 0.005;
  bool write_xdmf = true;  ///< keep <path without extension>.xmf next to the file
  /// The sidecar is rewritten at every flush while the run has at most this many frames; later
  /// only once the frames written since its last rewrite reach `xdmf_growth` times the frames
  /// it holds (a whole rewrite each time: O(frames) in total, not O(frames^2)), and at Close.
  std::int64_t xdmf_every_flush_frames = 1000;
  double xdmf_growth = 0.25;
  /// Simulated time between the frames the sidecar lists (XdmfRun::interval_s; 0 = every frame).
  double xdmf_interval_s = kXdmfIntervalS;
  /// Frames are buffered in memory and written as blocks (one extent change and one write per
  /// dataset per block: HDF5's cost is per call). A block is written at every flush, at Close()
  /// and when it holds `block_frames` frames or `block_bytes` bytes. 1 = every frame at once.
  std::int64_t block_frames = 64;
  std::size_t block_bytes = std::size_t{16} << 20;
  /// Full checkpoints in /checkpoints (at the first frame, then at the first frame of every
  /// Model::options.checkpoint_every_s of simulated time, and by WriteCheckpoint).
  bool checkpoints = true;
  /// zlib level of the checkpoint bytes.
  int checkpoint_deflate_level = 6;
  /// Compress and store chunks, flush the file and rewrite the sidecar on a writer thread, in
  /// the order the step thread queues them, so that Append never waits for them (the file is
  /// the same byte for byte as with false, where all of it runs inside Append). A flush waits
  /// only while the thread has more than `max_flushes_behind` flushes still to do (memory stays
  /// bounded by about that many flush intervals of frames when the disk is slow).
  bool background_writer = true;
  int max_flushes_behind = 1;
  RunOrigin origin;
};

class RunWriter {
 public:
  /// Creates `path` (truncating it) with datasets for every body, bone, thread and instrument of
  /// `model`, and writes `initial` as frame 0. The Model and State must match (same counts).
  /// @throws InputError (file = path, field output_file) if the file cannot be created;
  ///         std::invalid_argument if `initial` does not fit `model`. No file is left behind.
  RunWriter(const std::string& path, const Model& model, const State& initial,
            RunWriterOptions options = {});
  /// Closes the file properly (errors are swallowed; call Close() to see them).
  ~RunWriter();
  RunWriter(const RunWriter&) = delete;
  RunWriter& operator=(const RunWriter&) = delete;

  /// Records the events of `s` (s.events, the events of step s.step). Call it after every step
  /// when frames are written less often than every step; Append() records them otherwise.
  void RecordEvents(const State& s);
  /// Appends `s` as the next frame (its step must be greater than the last frame's): buffered,
  /// written with its block. Flushes when s.time_s has advanced Model::options.flush_interval_s
  /// or more since the last flush (queued for the writer thread: after a kill -9 the file holds
  /// every frame up to the last flush that thread finished). No C++ heap allocation in steady state
  /// (buffers are reused).
  /// @throws std::invalid_argument if `s` does not fit the model (checked before any write).
  void Append(const State& s);
  /// Stores a full, exact checkpoint of `s` (every State field; core/state_bytes.h) in
  /// /checkpoints and flushes, so that it is durable. Append does this by itself on the
  /// checkpoint schedule; call it for the last state of a run (finished or interrupted). Does
  /// nothing when the last checkpoint already has s's step or checkpoints are off.
  void WriteCheckpoint(const State& s);
  /// Makes every frame written so far durable and readable by SWMR readers; rewrites the .xmf.
  /// Returns once it is done (the flushes Append makes by itself return at once and are done by
  /// the writer thread).
  void Flush();
  /// Flushes, writes the .xmf and closes. Further Append/Flush calls throw std::logic_error.
  void Close();

  /// Frames appended so far (including frame 0), buffered or in the file.
  std::int64_t frames() const;
  /// Checkpoints written so far.
  std::int64_t checkpoints() const;
  /// Frames made durable by the last flush that finished (on the writer thread, the flushes
  /// queued by Append finish after Append returns).
  std::int64_t flushed_frames() const;
  const std::string& path() const;
  /// The sidecar path ("" when options.write_xdmf is false).
  const std::string& xdmf_path() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace arthrosim::io
