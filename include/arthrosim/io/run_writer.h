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

struct RunWriterOptions {
  /// zlib level 0..9 (with byte shuffle) for integer, mask, index, record and small float
  /// datasets: they shrink many-fold at little cost.
  int deflate_level = 4;
  /// zlib level (with byte shuffle) for the bulk coordinates (positions, bone vertices). The
  /// quantised positions' low mantissa bytes are zero and unmoved nodes repeat the previous
  /// block's bytes, so they shrink ~10-fold.
  int float_deflate_level = 4;
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
  /// or more since the last flush. No C++ heap allocation in steady state (buffers are reused).
  /// @throws std::invalid_argument if `s` does not fit the model (checked before any write).
  void Append(const State& s);
  /// Makes every frame written so far durable and readable by SWMR readers; rewrites the .xmf.
  void Flush();
  /// Flushes, writes the .xmf and closes. Further Append/Flush calls throw std::logic_error.
  void Close();

  /// Frames appended so far (including frame 0), buffered or in the file.
  std::int64_t frames() const;
  /// Frames made durable by the last flush.
  std::int64_t flushed_frames() const;
  const std::string& path() const;
  /// The sidecar path ("" when options.write_xdmf is false).
  const std::string& xdmf_path() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace arthrosim::io
