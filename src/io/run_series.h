#pragma once
// Private building blocks of RunWriter: a per-frame series ([T, ...] growing along time and
// optionally along the node/element dimension), an append-only row series and a block series
// (concatenated rows written only when they change, with per-frame offset/count datasets).
//
// All of them buffer in memory and store **whole chunks** with H5Dwrite_chunk, compressed here
// exactly as HDF5's shuffle + deflate filters would (readers see ordinary filtered chunks):
// * under SWMR, HDF5 1.10 never reuses the file space of a chunk written part-filled and
//   rewritten later (a third of a run file was such lost space), so a chunk is written when it
//   is full; RunWriter flushes on chunk boundaries of the per-frame series and block series pad
//   their last chunk before a flush;
// * under SWMR, HDF5 1.10 keeps in memory every chunk that H5Dwrite wrote until the file is
//   closed (~200 MB over a 10-minute run); H5Dwrite_chunk keeps nothing.
#include <array>
#include <cstdint>
#include <initializer_list>
#include <string>
#include <vector>

#include "arthrosim/io/hdf5.h"

namespace arthrosim::io::detail {

class WriteQueue;

/// Turns one chunk of elements in memory layout into the bytes HDF5 stores for it: conversion
/// to the file type (compound records differ), byte shuffle and deflate (zlib format).
class ChunkCodec {
 public:
  /// `deflate` 0 = stored raw (no filters on the dataset).
  void Init(hid_t mem_type, hid_t file_type, int deflate);
  /// Encodes `count` elements at `data` (memory layout) and stores them as the chunk at
  /// `offset` of `ds`. No C++ heap allocation once the scratch buffers have grown.
  void Write(h5::Dataset& ds, const hsize_t* offset, const unsigned char* data, std::size_t count);
  hid_t mem_type() const { return mem_type_; }
  std::size_t mem_bytes() const { return mem_bytes_; }

 private:
  hid_t mem_type_ = -1, file_type_ = -1;
  std::size_t mem_bytes_ = 0, file_bytes_ = 0;
  bool convert_ = false;
  int level_ = 0;
  std::vector<unsigned char> converted_, background_, shuffled_, compressed_;
};

/// A dataset with one row per frame, shape [T, row...] (rank <= kMaxRank). Dimensions listed in
/// `also_grow` (1-based in the full shape) may grow; rows that did not exist yet in a frame hold
/// the fill value.
class FrameSeries {
 public:
  static constexpr int kMaxRank = 4;

  /// Creates `name` in `g` with initial row shape `row`; frames are given in `mem_type`.
  /// `chunk_frames` frames per chunk (RunWriter: the frames between two flushes; a divisor of
  /// it for long rows or long intervals).
  void Create(h5::Group& g, const std::string& name, hid_t file_type, hid_t mem_type,
              std::vector<hsize_t> row, std::vector<int> also_grow, const void* fill, int deflate,
              hsize_t chunk_frames);
  /// Buffers the next frame: `row_count` elements per row dimension (one entry per row
  /// dimension; fewer than the row shape are padded by the fill value, more grow it).
  void Write(std::initializer_list<hsize_t> row_count, const void* data);
  template <class T>
  void Push(const T& value) {
    PushBytes(&value, sizeof(T));
  }
  /// Stores the buffered frames' full chunks; with `partial` also the last, part-filled chunk
  /// (it is stored again, whole, once full). Grows the extent to the frames stored.
  void WriteOut(bool partial = false);

  /// Frames stored in the file plus frames buffered.
  hsize_t frames() const { return frames_; }
  std::size_t buffered_bytes() const { return buf_.size(); }
  hsize_t chunk_frames() const { return chunk_[0]; }
  /// From now on extents and chunks go through `queue` (write_queue.h; nullptr: stored at once).
  void set_queue(WriteQueue* queue) { queue_ = queue; }

 private:
  void PushBytes(const void* value, std::size_t bytes);
  std::size_t RowElements() const;
  /// Re-lays the buffered frames out for the row shape `row` (bigger), padding with the fill.
  void Regrow(const hsize_t* row);
  /// Stores the chunks of frames [t0, t0 + nt) (all chunks along the row dimensions).
  void WriteChunks(hsize_t t0, hsize_t nt);

  h5::Dataset ds_;
  ChunkCodec codec_;
  WriteQueue* queue_ = nullptr;
  std::size_t element_bytes_ = 0;  // of the memory type
  int rank_ = 0;
  std::array<hsize_t, kMaxRank> row_{};            // [-, row shape of the buffered frames]
  std::array<hsize_t, kMaxRank> chunk_{};          // chunk shape
  std::array<hsize_t, kMaxRank> extent_{};         // extent in the file
  hsize_t first_ = 0;                              // first buffered frame: a chunk boundary
  hsize_t frames_ = 0;                             // frames stored and buffered
  std::vector<unsigned char> fill_;                // one element
  std::vector<unsigned char> buf_;                 // frames [first_, frames_) at row shape row_
  std::vector<unsigned char> chunk_buf_, regrow_;  // scratch
};

/// Append-only rows of a 1-D (compound records, `columns` 0) or [rows, columns] dataset, stored
/// chunk by chunk as chunks fill up.
class RowSeries {
 public:
  enum class Tail {
    kKeep,     ///< the part-filled last chunk stays in memory
    kPartial,  ///< stored as it is (stored again when it changes: its old space is lost)
    kSeal,     ///< filled up with zero rows first (RowSeries then starts a new chunk)
  };
  /// `chunk_rows` > 0 sets the rows per chunk (default ~64 KiB of rows).
  void Create(h5::Group& g, const std::string& name, hid_t file_type, hid_t mem_type, int columns,
              std::size_t row_bytes, int deflate, hsize_t chunk_rows = 0);
  /// Appends `rows` rows at `data`; stores every chunk it fills.
  void Append(const void* data, std::int64_t rows);
  /// Stores the part-filled last chunk as `tail` says and grows the extent to the rows stored.
  void WriteOut(Tail tail);

  std::int64_t total_rows() const { return total_; }
  std::int64_t chunk_rows() const { return chunk_rows_; }
  std::size_t buffered_bytes() const { return pending_.size(); }
  const std::string& path() const { return ds_.path(); }
  h5::Dataset& dataset() { return ds_; }
  /// As FrameSeries::set_queue.
  void set_queue(WriteQueue* queue) { queue_ = queue; }

 private:
  void StoreFullChunks();

  h5::Dataset ds_;
  ChunkCodec codec_;
  WriteQueue* queue_ = nullptr;
  int columns_ = 0;
  std::size_t row_bytes_ = 0;
  std::int64_t chunk_rows_ = 1;
  std::int64_t total_ = 0;              // rows appended (sealing padding included)
  std::int64_t first_ = 0;              // first row in pending_: a chunk boundary
  std::int64_t extent_ = 0;             // rows in the file's extent
  std::int64_t stored_tail_ = -1;       // total_ when the part-filled chunk was last stored
  std::vector<unsigned char> pending_;  // rows [first_, total_)
};

/// Concatenated rows + `<name>_offset` [T] int64 + `<name>_count` [T] int64. A new block is
/// appended only when its bytes differ from the previous block.
class BlockSeries {
 public:
  /// As RowSeries::Create; the offsets and counts have `chunk_frames` frames per chunk.
  void Create(h5::Group& g, const std::string& name, hid_t file_type, hid_t mem_type, int columns,
              std::size_t row_bytes, int deflate, hsize_t chunk_frames, hsize_t chunk_rows = 0);
  /// Buffers the next frame's block: `rows` rows at `data`.
  void Write(const void* data, std::int64_t rows);
  /// Without `seal`, nothing (full chunks of rows are stored as they fill). With `seal` (before
  /// a flush): the part-filled last chunk of rows is filled up with zero rows that no frame
  /// refers to (they compress to almost nothing) and stored, then the buffered offsets and
  /// counts (rows before the references to them).
  void WriteOut(bool seal = false);

  std::int64_t total_rows() const { return data_.total_rows(); }
  /// The last frame's block: first row and row count.
  std::int64_t last_offset() const { return last_offset_; }
  std::int64_t last_count() const { return last_count_; }
  const std::string& path() const { return data_.path(); }
  std::size_t buffered_bytes() const {
    return data_.buffered_bytes() + offset_.buffered_bytes() + count_.buffered_bytes();
  }
  /// As FrameSeries::set_queue, for the rows and the offsets and counts.
  void set_queue(WriteQueue* queue) {
    data_.set_queue(queue), offset_.set_queue(queue), count_.set_queue(queue);
  }

 private:
  RowSeries data_;
  FrameSeries offset_, count_;
  std::size_t row_bytes_ = 0;
  bool has_last_ = false;
  std::vector<unsigned char> last_;                // the previous frame's block
  std::int64_t last_offset_ = 0, last_count_ = 0;  // the last frame's block
};

}  // namespace arthrosim::io::detail
