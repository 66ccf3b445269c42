#pragma once
// Private building blocks of RunWriter: a per-frame series ([T, ...] growing along time and
// optionally along the node/element dimension) and a block series (concatenated rows written
// only when they change, with per-frame offset/count datasets).
//
// Both buffer frames in memory and write them in blocks (one extent change and one hyperslab
// write per dataset per block): HDF5's cost is per call, not per byte, and ~60 datasets written
// every frame cost more than the bytes. RunWriter decides when a block is written (WriteOut).
#include <array>
#include <cstdint>
#include <initializer_list>
#include <string>
#include <vector>

#include "arthrosim/io/hdf5.h"

namespace arthrosim::io::detail {

/// A dataset with one row per frame, shape [T, row...] (rank <= kMaxRank). Dimensions listed in
/// `also_grow` (1-based in the full shape) may grow; rows that did not exist yet in a frame hold
/// the fill value.
class FrameSeries {
 public:
  static constexpr int kMaxRank = 4;
  /// Frames per chunk at most (~2.5 s at 50 frames/s).
  static constexpr hsize_t kChunkFrames = 128;

  /// Creates `name` in `g` with initial row shape `row`; frames are given in `mem_type`.
  void Create(h5::Group& g, const std::string& name, hid_t file_type, hid_t mem_type,
              std::vector<hsize_t> row, std::vector<int> also_grow, const void* fill, int deflate);
  /// Buffers the next frame: `row_count` elements per row dimension (one entry per row
  /// dimension; fewer than the extent are padded by the fill value, more grow the dataset).
  /// A row shape other than the buffered frames' writes those out first (a block has one shape).
  void Write(std::initializer_list<hsize_t> row_count, const void* data);
  template <class T>
  void Push(const T& value) {
    PushBytes(&value, sizeof(T));
  }
  /// Writes the buffered frames to the file (one extent change, one write); no-op when empty.
  void WriteOut();

  /// Frames written to the file plus frames buffered.
  hsize_t frames() const { return written_ + buffered_; }
  std::size_t buffered_bytes() const { return buf_.size(); }

 private:
  void PushBytes(const void* value, std::size_t bytes);

  h5::Dataset ds_;
  hid_t mem_type_ = -1;
  std::size_t element_bytes_ = 0;  // of mem_type_
  int rank_ = 0;
  std::array<hsize_t, kMaxRank> dims_{};   // current extent in the file
  std::array<hsize_t, kMaxRank> shape_{};  // [0, row shape of the buffered frames]
  hsize_t written_ = 0, buffered_ = 0;
  std::vector<unsigned char> buf_;  // buffered frames, contiguous rows of shape_
};

/// Concatenated rows + `<name>_offset` [T] int64 + `<name>_count` [T] int64. A new block is
/// appended only when its bytes differ from the previous block.
class BlockSeries {
 public:
  /// `columns` == 0 makes a 1-D dataset of `file_type` rows (compound records); rows are given
  /// in `mem_type`, `row_bytes` each.
  /// `chunk_rows` > 0 sets the rows per chunk (default ~64 KiB of rows).
  void Create(h5::Group& g, const std::string& name, hid_t file_type, hid_t mem_type, int columns,
              std::size_t row_bytes, int deflate, hsize_t chunk_rows = 0);
  /// Buffers the next frame's block: `rows` rows at `data`.
  void Write(const void* data, std::int64_t rows);
  /// Writes the buffered rows, then the buffered offsets and counts (rows before references).
  void WriteOut();

  std::int64_t total_rows() const { return total_; }
  /// The last frame's block: first row and row count.
  std::int64_t last_offset() const { return last_offset_; }
  std::int64_t last_count() const { return last_count_; }
  const std::string& path() const { return data_.path(); }
  std::size_t buffered_bytes() const {
    return pending_.size() + offset_.buffered_bytes() + count_.buffered_bytes();
  }

 private:
  h5::Dataset data_;
  hid_t mem_type_ = -1;
  int columns_ = 0;
  FrameSeries offset_, count_;
  std::size_t row_bytes_ = 0;
  std::int64_t total_ = 0;         // rows, written and buffered
  std::int64_t written_rows_ = 0;  // rows in the file
  // The previous frame's block: at pending_[last_pos_, +last_bytes_) while it is buffered, else a
  // copy in last_ (made once per written block, not per frame).
  bool has_last_ = false, last_in_pending_ = false;
  std::size_t last_pos_ = 0, last_bytes_ = 0;
  std::vector<unsigned char> last_;
  std::vector<unsigned char> pending_;             // new rows not yet written
  std::int64_t last_offset_ = 0, last_count_ = 0;  // the last frame's block
};

}  // namespace arthrosim::io::detail
