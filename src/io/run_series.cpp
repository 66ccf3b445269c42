#include "run_series.h"

#include <algorithm>
#include <cstring>
#include <stdexcept>

#include "arthrosim/io/hdf5_layout.h"

namespace arthrosim::io::detail {

void FrameSeries::Create(h5::Group& g, const std::string& name, hid_t file_type, hid_t mem_type,
                         std::vector<hsize_t> row, std::vector<int> also_grow, const void* fill,
                         int deflate) {
  if (row.size() + 1 > kMaxRank) throw std::logic_error("FrameSeries: rank too high: " + name);
  std::vector<hsize_t> dims{0};
  dims.insert(dims.end(), row.begin(), row.end());
  const std::size_t file_bytes = H5Tget_size(file_type);
  h5::DatasetSpec spec = h5::GrowingSpec(dims, file_bytes, std::move(also_grow));
  // At most kChunkFrames frames per chunk: every flush rewrites the part-filled chunk of each
  // compressed dataset at a new place in the file (the old one is lost: HDF5 reuses little of
  // it), so long chunks of small rows wasted about a third of the file.
  spec.chunk[0] = std::min(spec.chunk[0], kChunkFrames);
  spec.deflate = deflate;
  spec.fill = fill;
  ds_ = g.CreateDataset(name, file_type, spec);
  mem_type_ = mem_type;
  element_bytes_ = H5Tget_size(mem_type);
  rank_ = static_cast<int>(dims.size());
  std::copy(dims.begin(), dims.end(), dims_.begin());
  shape_ = dims_;
}

void FrameSeries::Write(std::initializer_list<hsize_t> row_count, const void* data) {
  if (static_cast<int>(row_count.size()) != rank_ - 1) {
    throw std::logic_error("FrameSeries::Write: row rank differs from " + ds_.path());
  }
  if (!std::equal(row_count.begin(), row_count.end(), shape_.begin() + 1)) {
    WriteOut();  // the buffered frames have the old shape
    std::copy(row_count.begin(), row_count.end(), shape_.begin() + 1);
  }
  std::size_t bytes = element_bytes_;
  for (hsize_t c : row_count) bytes *= c;
  const auto* p = static_cast<const unsigned char*>(data);
  buf_.insert(buf_.end(), p, p + bytes);
  ++buffered_;
}

void FrameSeries::PushBytes(const void* value, std::size_t bytes) {
  if (rank_ != 1 || bytes != element_bytes_) {
    throw std::logic_error("FrameSeries::Push: not a scalar of this type: " + ds_.path());
  }
  const auto* p = static_cast<const unsigned char*>(value);
  buf_.insert(buf_.end(), p, p + bytes);
  ++buffered_;
}

void FrameSeries::WriteOut() {
  if (buffered_ == 0) return;
  std::array<hsize_t, kMaxRank> dims = dims_;
  dims[0] = written_ + buffered_;
  for (int d = 1; d < rank_; ++d) dims[d] = std::max(dims[d], shape_[d]);
  ds_.SetExtent(rank_, dims.data());
  dims_ = dims;
  std::array<hsize_t, kMaxRank> start{};
  std::array<hsize_t, kMaxRank> count = shape_;
  start[0] = written_;
  count[0] = buffered_;
  ds_.Write(rank_, start.data(), count.data(), mem_type_, buf_.data());
  written_ += buffered_;
  buffered_ = 0;
  buf_.clear();  // keeps the capacity: the next block reuses it
}

void BlockSeries::Create(h5::Group& g, const std::string& name, hid_t file_type, hid_t mem_type,
                         int columns, std::size_t row_bytes, int deflate, hsize_t chunk_rows) {
  row_bytes_ = row_bytes;
  mem_type_ = mem_type;
  columns_ = columns;
  std::vector<hsize_t> dims{0};
  std::size_t element_bytes = H5Tget_size(file_type);
  if (columns > 0) dims.push_back(static_cast<hsize_t>(columns));
  if (columns == 0) element_bytes = row_bytes;  // compound rows: chunked by their memory size
  h5::DatasetSpec spec = h5::GrowingSpec(dims, element_bytes);
  if (chunk_rows > 0) spec.chunk[0] = chunk_rows;
  spec.deflate = deflate;
  data_ = g.CreateDataset(name, file_type, spec);
  offset_.Create(g, layout::OffsetName(name), H5T_STD_I64LE, H5T_NATIVE_INT64, {}, {}, nullptr,
                 deflate);
  count_.Create(g, layout::CountName(name), H5T_STD_I64LE, H5T_NATIVE_INT64, {}, {}, nullptr,
                deflate);
}

void BlockSeries::Write(const void* data, std::int64_t rows) {
  const std::size_t bytes = static_cast<std::size_t>(rows) * row_bytes_;
  const unsigned char* last = last_in_pending_ ? pending_.data() + last_pos_ : last_.data();
  const bool same =
      has_last_ && last_bytes_ == bytes && (bytes == 0 || std::memcmp(last, data, bytes) == 0);
  if (!same) {
    const auto* p = static_cast<const unsigned char*>(data);
    last_pos_ = pending_.size();
    last_bytes_ = bytes;
    last_in_pending_ = true;
    has_last_ = true;
    pending_.insert(pending_.end(), p, p + bytes);
    last_offset_ = total_;
    last_count_ = rows;
    total_ += rows;
  }
  offset_.Push(last_offset_);
  count_.Push(last_count_);
}

void BlockSeries::WriteOut() {
  const std::int64_t rows = total_ - written_rows_;
  if (rows > 0) {
    const int rank = columns_ > 0 ? 2 : 1;
    const hsize_t dims[2] = {static_cast<hsize_t>(total_), static_cast<hsize_t>(columns_)};
    const hsize_t start[2] = {static_cast<hsize_t>(written_rows_), 0};
    const hsize_t count[2] = {static_cast<hsize_t>(rows), static_cast<hsize_t>(columns_)};
    data_.SetExtent(rank, dims);
    data_.Write(rank, start, count, mem_type_, pending_.data());
    written_rows_ = total_;
  }
  if (last_in_pending_) {  // keep the last block for the next comparison
    last_.assign(pending_.begin() + static_cast<std::ptrdiff_t>(last_pos_),
                 pending_.begin() + static_cast<std::ptrdiff_t>(last_pos_ + last_bytes_));
    last_in_pending_ = false;
  }
  pending_.clear();
  offset_.WriteOut();
  count_.WriteOut();
}

}  // namespace arthrosim::io::detail
