#pragma once
// Private to RunWriter: the per-entity output datasets and RunWriter::Impl, shared by
// run_writer.cpp (frames, blocks, flushes, the sidecar) and run_writer_layout.cpp (creating
// every group and dataset up front).
#include <algorithm>
#include <array>
#include <atomic>
#include <cstdint>
#include <limits>
#include <memory>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

#include "arthrosim/core/model.h"
#include "arthrosim/core/state.h"
#include "arthrosim/io/hdf5.h"
#include "arthrosim/io/hdf5_layout.h"
#include "arthrosim/io/run_writer.h"
#include "arthrosim/io/xdmf.h"
#include "run_series.h"
#include "state_datasets.h"
#include "write_queue.h"

namespace arthrosim::io {
namespace detail {

inline constexpr std::int8_t kNoSlot = -1;

/// The per-frame datasets of an entity's fields stored per frame (FieldStore::kFrame), in the
/// order the State field table visits them.
struct FieldSet {
  std::vector<FrameSeries> series;
  std::vector<detail::ValueType> types;
  std::vector<std::vector<unsigned char>> rows;  // per-slot values gathered for one frame
  std::vector<std::size_t> row_bytes;            // bytes of one slot's value
  std::vector<std::uint8_t> pad;                 // per-node marks padded to the node count
};

/// Creates a dataset in g for every per-frame field of `sample` (rows of `slots` values when
/// slots > 0), `chunk` frames per chunk. `skip` (a member of sample, or nullptr) gets none.
template <class S>
void CreateFields(h5::Group& g, const S& sample, hsize_t slots, int z, int zf, hsize_t chunk,
                  FieldSet* out, const void* skip = nullptr, bool nan_poses = false,
                  hsize_t nodes = 0) {
  VisitFields(sample, [&](const auto& value, const FieldInfo& info) {
    using T = std::decay_t<decltype(value)>;
    if (info.store != FieldStore::kFrame || static_cast<const void*>(&value) == skip) return;
    if constexpr (detail::kFrameValue<T>) {
      const detail::ValueType t = detail::TypeOf<T>();
      std::vector<hsize_t> row;
      std::vector<int> grow;
      if (slots > 0) row.push_back(slots);
      if (t.per_node) {
        row.push_back(info.dim == FieldDim::kNodes && nodes > 0 ? nodes : detail::RowsOf(value));
        grow.push_back(static_cast<int>(row.size()));
      }
      if (t.row_vector) row.push_back(detail::RowsOf(value));
      if (t.width > 0) row.push_back(t.width);
      const FieldFill fill = nan_poses && std::is_same_v<T, Pose> ? FieldFill::kNaN : info.fill;
      out->series.emplace_back().Create(g, info.name, t.file, t.mem, row, grow,
                                        detail::FillOf<T>(fill), info.bulk_float ? zf : z, chunk);
      out->types.push_back(t);
      const std::size_t bytes = detail::BytesOf(value);
      out->row_bytes.push_back(bytes);
      out->rows.emplace_back(bytes * (slots > 0 ? slots : 1));
    } else {
      throw std::logic_error(std::string("RunWriter: field '") + info.name +
                             "' has a type that cannot be stored per frame");
    }
  });
}

/// Buffers one frame of a dataset: `rows` rows (nodes, elements; 1 for fixed shapes).
inline void WriteRow(FrameSeries& series, const detail::ValueType& t, hsize_t slots, hsize_t rows,
                     const void* data) {
  const hsize_t w = t.width;
  if (slots > 0) {
    if (w > 0) return series.Write({slots, w}, data);
    return series.Write({slots}, data);
  }
  if (t.per_node || t.row_vector) {
    if (w > 0) return series.Write({rows, w}, data);
    return series.Write({rows}, data);
  }
  if (w > 0) return series.Write({w}, data);
  series.Write({}, data);
}

/// Buffers the per-frame fields of s (one entity with `nodes` nodes) as the next frame. Per-node
/// marks shorter than the node count are padded with zeros. No heap allocation in steady state.
template <class S>
void WriteFields(const S& s, FieldSet* f, const void* skip = nullptr, hsize_t nodes = 0) {
  std::size_t i = 0;
  std::array<double, 7> pose;
  VisitFields(s, [&](const auto& value, const FieldInfo& info) {
    using T = std::decay_t<decltype(value)>;
    if (info.store != FieldStore::kFrame || static_cast<const void*>(&value) == skip) return;
    if constexpr (std::is_same_v<T, std::vector<std::uint8_t>>) {
      if (info.dim == FieldDim::kNodes && value.size() != nodes) {
        f->pad.assign(nodes, 0);
        std::copy_n(value.begin(), std::min<std::size_t>(value.size(), nodes), f->pad.begin());
        WriteRow(f->series[i], f->types[i], 0, nodes, f->pad.data());
        ++i;
        return;
      }
    }
    if constexpr (detail::kFrameValue<T>) {
      WriteRow(f->series[i], f->types[i], 0, detail::RowsOf(value), detail::DataOf(value, &pose));
      ++i;
    }
  });
}

/// Buffers one frame of per-slot fields: field j of every slot as one [slots, ...] row.
template <class S, std::size_t N>
void WriteSlotFields(const std::array<S, N>& slots, FieldSet* f) {
  std::array<double, 7> pose;
  for (std::size_t k = 0; k < N; ++k) {
    std::size_t j = 0;
    VisitFields(slots[k], [&](const auto& value, const FieldInfo& info) {
      using T = std::decay_t<decltype(value)>;
      if (info.store != FieldStore::kFrame) return;
      if constexpr (detail::kFrameValue<T>) {
        const auto* p = static_cast<const unsigned char*>(detail::DataOf(value, &pose));
        std::copy(p, p + f->row_bytes[j], f->rows[j].data() + k * f->row_bytes[j]);
        ++j;
      }
    });
  }
  for (std::size_t j = 0; j < f->series.size(); ++j) {
    WriteRow(f->series[j], f->types[j], N, 1, f->rows[j].data());
  }
}

/// Calls f on every series of a field set.
template <class F>
void ForEach(FieldSet& set, F& f) {
  for (FrameSeries& s : set.series) f(s);
}

struct BodyOut {
  FieldSet fields;
  FrameSeries node_count, element_count;
  h5::Dataset elements;
  std::vector<mesh::Tet> written;  // rows of /elements so far (append-only check)
  BlockSeries alive_elements, positions;
  std::vector<double> held;  // positions as stored (quantised, held within the tolerance)
};

struct ThreadOut {
  FieldSet fields;
  FrameSeries node_count;
  BlockSeries alive_segments, positions;
  std::vector<double> held;  // positions as stored (quantised, held within the tolerance)
};

struct BoneOut {
  FieldSet fields;
  BlockSeries vertices, triangles;
};

/// The per-instrument view of the tool slots (/tools/<instrument>).
struct ToolOut {
  FieldSet fields;  // the slot's fields but `instrument`; NaN pose while not inserted
  FrameSeries active, slot;
};

/// The /checkpoints datasets and what writing them needs (run_checkpoint.cpp).
struct CheckpointOut {
  RowSeries bytes;  // each checkpoint starts a chunk (sealed after it)
  RowSeries offset, size, step, frame, hash, time;
  State reference;                   // checkpoint bytes are XORed with it: the initial State
  std::vector<std::uint8_t> buffer;  // encoding of the last checkpoint (capacity reused)
  std::int64_t every_steps = 0;      // 0 = checkpoints off
  std::int64_t count = 0;            // queued (the writer thread may not have stored them yet)
  std::int64_t last_step = -1;       // step of the last checkpoint (-1 = none yet)
  // The State the writer thread stores next (StoreCheckpoint) and its frame; `queued` jobs of
  // which `done` have run (the step thread refills `pending` only when they are equal).
  State pending;
  std::int64_t pending_frame = -1;
  std::int64_t queued = 0;
  std::atomic<std::int64_t> done{0};
};

}  // namespace detail

struct RunWriter::Impl {
  std::string path, xmf_path;
  RunWriterOptions options;
  // Copied from the Model (the writer does not keep a reference to it).
  std::vector<std::string> body_names, thread_names, bone_names;
  std::size_t instrument_count = 0;
  double flush_interval_s = 1.0;
  /// Frames between two flushes (Model flush interval / frame interval, at least 1); also the
  /// frames per chunk of every per-frame dataset, so that a flush writes whole chunks.
  std::int64_t flush_frames = 1;
  h5::File file;
  bool closed = false;

  detail::FieldSet root_fields;  // step, time, next_constraint_id, rng_state
  std::size_t time_series = 0;   // index of /time in root_fields: written last
  detail::FrameSeries events_end;
  detail::RowSeries events;
  h5::Handle event_mem, event_file, constraint_mem, constraint_file, contact_mem, contact_file;
  std::vector<detail::BodyOut> bodies;
  std::vector<detail::ThreadOut> threads;
  std::vector<detail::BoneOut> bones;
  std::vector<detail::ToolOut> tools;
  ToolState absent;  // what /tools/<instrument> holds while it is not inserted
  detail::FieldSet slots, camera;
  detail::BlockSeries constraints, contacts;
  detail::BlockSeries holes,
      anchors;  // float64 rows: AppendHoleRow / AppendAnchorRow of hdf5_layout.h
  detail::CheckpointOut checkpoint;

  std::int64_t frames = 0, flushed = 0;
  std::int64_t xdmf_frames = 0;     // frames in the sidecar as last written
  std::int64_t written_frames = 0;  // frames whose every dataset is in the file (/time last)
  std::int64_t last_step = std::numeric_limits<std::int64_t>::min();
  std::int64_t last_events_step = std::numeric_limits<std::int64_t>::min();
  std::int64_t events_total = 0;
  std::vector<layout::EventRecord> pending_events;  // recorded since the last frame
  std::vector<layout::EventRecord> frame_events;    // of buffered frames, not yet in the file
  double last_time_s = 0;                           // of the last frame
  // The sidecar's frames (listed XdmfRun::interval_s apart: memory grows by ~10 entries per
  // simulated second, not 50) and their blocks; the series' total_rows are set when written.
  XdmfRun listed;
  double last_listed_s = 0;
  // What the writer thread writes as the sidecar (a copy of `listed` plus the last frame): the
  // step thread refills it only once the previous sidecar job has run.
  XdmfRun sidecar;
  std::int64_t sidecar_queued = 0;
  std::atomic<std::int64_t> sidecar_done{0};

  // Scratch buffers reused every frame.
  std::vector<std::int32_t> ints;
  std::vector<layout::ConstraintRecord> records;
  std::vector<layout::ToolContactRecord> contact_records;
  std::vector<double> record_rows;
  mutable std::vector<int> seen;  // Validate: slots holding each instrument

  hsize_t chunk() const { return static_cast<hsize_t>(flush_frames); }
  void CreateLayout(const Model& model, const State& initial);
  void CreateRoot(const Model& model, const State& initial);
  void CreateBodies(const Model& model, const State& initial);
  void CreateThreads(const Model& model, const State& initial);
  void CreateBones(const Model& model, const State& initial);
  void CreateTools(const Model& model, const State& initial);
  void CreateRecords();
  /// /checkpoints and the run's origin (/meta attributes); run_checkpoint.cpp.
  void CreateCheckpoints(const Model& model);
  /// True when s (just written as a frame) starts a new checkpoint interval.
  bool CheckpointDue(const State& s) const;
  /// Queues s to be encoded and appended to /checkpoints (not flushed); `frame` = its frame or
  /// -1.
  void AppendCheckpoint(const State& s, std::int64_t frame);
  /// The checkpoint job (writer thread): encodes and stores `checkpoint.pending` of the Impl at
  /// `impl`.
  static void StoreCheckpoint(void* impl);
  void Validate(const State& s) const;
  /// Buffers `s` as the next frame; writes the buffered block when it is full.
  void WriteFrame(const State& s);
  void WriteBodies(const State& s);
  void WriteThreads(const State& s);
  void WriteBones(const State& s);
  void WriteInstruments(const State& s);
  void WriteRecords(const State& s);
  void WriteEvents(const State& s);
  /// Writes every buffered frame to the file: all datasets, then /time (a frame counts once
  /// /time has it, so a reader never sees part of a frame). `seal` (before a flush): block
  /// series fill their part-filled last chunk (BlockSeries::WriteOut).
  void WriteBlock(bool seal = false);
  /// Calls f on every per-frame and block series except /time, in write order.
  template <class F>
  void ForEachSeries(F f);
  std::size_t BufferedBytes();
  /// Names the sidecar's meshes and series (after the layout is created).
  void CreateXdmf();
  /// Calls f(sidecar series, block series) for the cells and points of every sidecar mesh.
  template <class F>
  void ForEachXdmfSeries(F f);
  /// Adds the frame just written to `listed` when it is due.
  void ListFrame(double time_s);
  /// Queues a rewrite of the sidecar listing the frames so far (the writer thread writes it).
  void WriteXdmf();
  /// The sidecar job (writer thread): writes `sidecar` of the Impl at `impl`.
  static void WriteSidecar(void* impl);
  /// Stores every buffered frame, flushes the file and rewrites the sidecar when due, all
  /// through the queue: returns before the writer thread has done it.
  void QueueFlush();
  /// Every series stores its chunks through `queue` (after the layout is created).
  void UseQueue();

  /// Runs the writer's HDF5 calls, zlib and sidecar writes in order, on a background thread
  /// unless RunWriterOptions::background_writer is false. Last member: destroyed first (its
  /// jobs point into the members above).
  std::unique_ptr<detail::WriteQueue> queue;
};

}  // namespace arthrosim::io
