#include "run_series.h"

#include <cstring>

#include "arthrosim/io/hdf5_layout.h"

namespace arthrosim::io::detail {

void FrameSeries::Create(h5::Group& g, const std::string& name, hid_t file_type,
                         std::size_t element_bytes, std::vector<hsize_t> row,
                         std::vector<int> also_grow, const void* fill, int deflate) {
  dims_ = {0};
  dims_.insert(dims_.end(), row.begin(), row.end());
  h5::DatasetSpec spec = h5::GrowingSpec(dims_, element_bytes, std::move(also_grow));
  spec.deflate = deflate;
  spec.fill = fill;
  ds_ = g.CreateDataset(name, file_type, spec);
}

void FrameSeries::Write(hsize_t t, const std::vector<hsize_t>& row_count, hid_t mem_type,
                        const void* data) {
  std::vector<hsize_t> dims = dims_;
  dims[0] = t + 1;
  for (std::size_t d = 0; d < row_count.size(); ++d) {
    dims[d + 1] = std::max(dims[d + 1], row_count[d]);
  }
  if (dims != dims_) {
    ds_.SetExtent(dims);
    dims_ = dims;
  }
  std::vector<hsize_t> start(dims.size(), 0), count(dims.size(), 1);
  start[0] = t;
  for (std::size_t d = 0; d < row_count.size(); ++d) count[d + 1] = row_count[d];
  ds_.Write(start, count, mem_type, data);
}

void BlockSeries::Create(h5::Group& g, const std::string& name, hid_t file_type, int columns,
                         std::size_t row_bytes, int deflate) {
  row_bytes_ = row_bytes;
  std::vector<hsize_t> dims{0};
  std::size_t element_bytes = row_bytes;
  if (columns > 0) {
    dims.push_back(static_cast<hsize_t>(columns));
    element_bytes = row_bytes / static_cast<std::size_t>(columns);
  }
  h5::DatasetSpec spec = h5::GrowingSpec(dims, element_bytes);
  spec.deflate = deflate;
  data_ = g.CreateDataset(name, file_type, spec);
  offset_.Create(g, layout::OffsetName(name), H5T_STD_I64LE, 8, {}, {}, nullptr, deflate);
  count_.Create(g, layout::CountName(name), H5T_STD_I64LE, 8, {}, {}, nullptr, deflate);
}

void BlockSeries::Write(hsize_t t, hid_t mem_type, const void* data, std::int64_t rows) {
  const std::size_t bytes = static_cast<std::size_t>(rows) * row_bytes_;
  const bool same = has_last_ && last_.size() == bytes &&
                    (bytes == 0 || std::memcmp(last_.data(), data, bytes) == 0);
  if (!same) {
    data_.AppendRows(mem_type, data, static_cast<hsize_t>(rows));
    const auto* p = static_cast<const unsigned char*>(data);
    last_.assign(p, p + bytes);
    offsets_.push_back(total_);
    counts_.push_back(rows);
    total_ += rows;
    has_last_ = true;
  } else {
    offsets_.push_back(offsets_.back());
    counts_.push_back(counts_.back());
  }
  offset_.Push(t, offsets_.back());
  count_.Push(t, counts_.back());
}

}  // namespace arthrosim::io::detail
