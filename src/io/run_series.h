#pragma once
// Private building blocks of RunWriter: a per-frame series ([T, ...] growing along time and
// optionally along the node/element dimension) and a block series (concatenated rows written
// only when they change, with per-frame offset/count datasets).
#include <cstdint>
#include <vector>

#include "arthrosim/io/hdf5.h"

namespace arthrosim::io::detail {

/// A dataset with one row per frame, shape [T, row...]. Dimensions listed in `also_grow` (1-based
/// in the full shape) may grow; rows that did not exist yet in a frame hold the fill value.
class FrameSeries {
 public:
  /// Creates `name` in `g` with initial row shape `row`.
  void Create(h5::Group& g, const std::string& name, hid_t file_type, std::size_t element_bytes,
              std::vector<hsize_t> row, std::vector<int> also_grow, const void* fill, int deflate);
  /// Writes frame `t` (== current frame count): `row_count` elements per row dimension
  /// (<= current extent is padded by the fill value; more grows the dataset).
  void Write(hsize_t t, const std::vector<hsize_t>& row_count, hid_t mem_type, const void* data);
  template <class T>
  void Push(hsize_t t, const T& value) {
    Write(t, {}, h5::NativeType<T>(), &value);
  }

 private:
  h5::Dataset ds_;
  std::vector<hsize_t> dims_;
};

/// Concatenated rows + `<name>_offset` [T] int64 + `<name>_count` [T] int64. A new block is
/// appended only when its bytes differ from the previous block.
class BlockSeries {
 public:
  /// `columns` == 0 makes a 1-D dataset of `file_type` rows (compound records).
  void Create(h5::Group& g, const std::string& name, hid_t file_type, int columns,
              std::size_t row_bytes, int deflate);
  /// Frame `t`'s block: `rows` rows of `row_bytes` each in memory type `mem_type`.
  void Write(hsize_t t, hid_t mem_type, const void* data, std::int64_t rows);

  std::int64_t total_rows() const { return total_; }
  const std::vector<std::int64_t>& offsets() const { return offsets_; }
  const std::vector<std::int64_t>& counts() const { return counts_; }
  const std::string& path() const { return data_.path(); }

 private:
  h5::Dataset data_;
  FrameSeries offset_, count_;
  std::size_t row_bytes_ = 0;
  std::int64_t total_ = 0;
  bool has_last_ = false;
  std::vector<unsigned char> last_;
  std::vector<std::int64_t> offsets_, counts_;  // mirrors of the index datasets (for XDMF)
};

}  // namespace arthrosim::io::detail
