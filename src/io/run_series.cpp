#include "run_series.h"

#include <zlib.h>

#include <algorithm>
#include <cstring>
#include <memory>
#include <stdexcept>

#include "arthrosim/io/hdf5_layout.h"
#include "write_queue.h"

namespace arthrosim::io::detail {
namespace {

// Frames per chunk: the interval, or its largest divisor that keeps a chunk within bounds (the
// writer buffers up to one chunk per dataset).
hsize_t ChunkFrames(hsize_t interval, std::size_t row_bytes) {
  constexpr hsize_t kMaxChunkFrames = 1024;
  constexpr std::size_t kMaxChunkBytes = std::size_t{1} << 20;
  interval = std::max<hsize_t>(interval, 1);
  for (hsize_t k = 1; k <= interval; ++k) {
    const hsize_t f = interval / k;
    if (interval % k == 0 && f <= kMaxChunkFrames && (f == 1 || f * row_bytes <= kMaxChunkBytes)) {
      return f;
    }
  }
  return 1;
}

// Grows ds's extent, through `queue` when there is one.
void SetExtentVia(WriteQueue* queue, h5::Dataset& ds, int rank, const hsize_t* dims) {
  if (queue != nullptr) return queue->SetExtent(&ds, rank, dims);
  ds.SetExtent(rank, dims);
}

// Compresses and stores one chunk, through `queue` when there is one (which copies `data`).
void StoreChunkVia(WriteQueue* queue, ChunkCodec& codec, h5::Dataset& ds, int rank,
                   const hsize_t* offset, const unsigned char* data, std::size_t count) {
  if (queue != nullptr) return queue->WriteChunk(&codec, &ds, rank, offset, data, count);
  codec.Write(ds, offset, data, count);
}

}  // namespace

// ---- ChunkCodec ------------------------------------------------------------------------------

void ChunkCodec::Init(hid_t mem_type, hid_t file_type, int deflate) {
  mem_type_ = mem_type;
  file_type_ = file_type;
  mem_bytes_ = H5Tget_size(mem_type);
  file_bytes_ = H5Tget_size(file_type);
  convert_ = H5Tequal(mem_type, file_type) <= 0;
  level_ = deflate;
}

namespace {
// zlib's memLevel for a chunk of `bytes`: a hash of about one entry per input byte (memLevel m
// hashes into 2^(m+7) entries). deflateReset clears the whole hash, so the default (m = 8, 64 KiB)
// for every few-kB chunk was a fifth of the flush's instructions; the stream format is the same.
int MemLevelFor(std::size_t bytes) {
  int bits = 0;
  while (bits < 30 && (std::size_t{1} << bits) < bytes) ++bits;
  return std::clamp(bits - 7, 1, 8);
}

// One deflate state per (level, memLevel), shared by every dataset of this thread (up to
// ~256 KiB each: one per dataset was 25 MB for the shoulder scene's ~100 datasets).
z_stream& Deflater(int level, int mem_level) {
  struct Streams {
    std::array<std::array<std::unique_ptr<z_stream>, 9>, 10> z;
    ~Streams() {
      for (auto& by_level : z) {
        for (auto& s : by_level) {
          if (s) deflateEnd(s.get());
        }
      }
    }
  };
  thread_local Streams streams;
  std::unique_ptr<z_stream>& s =
      streams.z[static_cast<std::size_t>(level)][static_cast<std::size_t>(mem_level)];
  if (!s) {
    auto z = std::make_unique<z_stream>();
    if (deflateInit2(z.get(), level, Z_DEFLATED, 15, mem_level, Z_DEFAULT_STRATEGY) != Z_OK) {
      throw std::runtime_error("zlib: deflateInit2");
    }
    s = std::move(z);
  }
  return *s;
}
}  // namespace

void ChunkCodec::Write(h5::Dataset& ds, const hsize_t* offset, const unsigned char* data,
                       std::size_t count) {
  const unsigned char* p = data;
  if (convert_) {  // to the file type, in place in a buffer big enough for either
    const std::size_t bytes = count * std::max(mem_bytes_, file_bytes_);
    converted_.resize(bytes);
    background_.resize(bytes);  // compound conversions need one
    std::memcpy(converted_.data(), data, count * mem_bytes_);
    if (H5Tconvert(mem_type_, file_type_, count, converted_.data(), background_.data(),
                   H5P_DEFAULT) < 0) {
      throw h5::Error(ds.file(), ds.path(), "cannot convert a chunk to the file type");
    }
    p = converted_.data();
  }
  const std::size_t bytes = count * file_bytes_;
  if (level_ == 0) return ds.WriteChunk(offset, p, bytes);
  // Byte shuffle (HDF5's shuffle filter, element size = the file type's): byte j of element i
  // goes to j * count + i.
  shuffled_.resize(bytes);
  for (std::size_t j = 0; j < file_bytes_; ++j) {
    unsigned char* out = shuffled_.data() + j * count;
    for (std::size_t i = 0; i < count; ++i) out[i] = p[i * file_bytes_ + j];
  }
  // Deflate (HDF5's deflate filter: zlib format at the dataset's level), one stream reused.
  z_stream& z = Deflater(level_, MemLevelFor(bytes));
  compressed_.resize(deflateBound(&z, static_cast<uLong>(bytes)));
  deflateReset(&z);
  z.next_in = shuffled_.data();
  z.avail_in = static_cast<uInt>(bytes);
  z.next_out = compressed_.data();
  z.avail_out = static_cast<uInt>(compressed_.size());
  if (deflate(&z, Z_FINISH) != Z_STREAM_END) {
    throw h5::Error(ds.file(), ds.path(), "cannot compress a chunk");
  }
  ds.WriteChunk(offset, compressed_.data(), compressed_.size() - z.avail_out);
}

// ---- FrameSeries -----------------------------------------------------------------------------

void FrameSeries::Create(h5::Group& g, const std::string& name, hid_t file_type, hid_t mem_type,
                         std::vector<hsize_t> row, std::vector<int> also_grow, const void* fill,
                         int deflate, hsize_t chunk_frames) {
  if (row.size() + 1 > kMaxRank) throw std::logic_error("FrameSeries: rank too high: " + name);
  std::vector<hsize_t> dims{0};
  dims.insert(dims.end(), row.begin(), row.end());
  h5::DatasetSpec spec = h5::GrowingSpec(dims, H5Tget_size(file_type), std::move(also_grow));
  std::size_t row_bytes = H5Tget_size(mem_type);
  for (std::size_t d = 1; d < spec.chunk.size(); ++d) row_bytes *= spec.chunk[d];
  spec.chunk[0] = ChunkFrames(chunk_frames, row_bytes);
  spec.deflate = deflate;
  spec.fill = fill;
  ds_ = g.CreateDataset(name, file_type, spec);
  codec_.Init(mem_type, file_type, deflate);
  element_bytes_ = H5Tget_size(mem_type);
  rank_ = static_cast<int>(dims.size());
  std::copy(dims.begin(), dims.end(), row_.begin());
  std::copy(dims.begin(), dims.end(), extent_.begin());
  std::copy(spec.chunk.begin(), spec.chunk.end(), chunk_.begin());
  fill_.assign(element_bytes_, 0);
  if (fill != nullptr) std::memcpy(fill_.data(), fill, element_bytes_);
  std::size_t chunk_elements = 1;
  for (int d = 0; d < rank_; ++d) chunk_elements *= chunk_[d];
  chunk_buf_.reserve(chunk_elements * element_bytes_);
  buf_.reserve(chunk_[0] * RowElements() * element_bytes_);
}

std::size_t FrameSeries::RowElements() const {
  std::size_t n = 1;
  for (int d = 1; d < rank_; ++d) n *= row_[d];
  return n;
}

// Copies a [rows...] block of shape `from` into one of shape `to` (each dim >= from's), the
// rest filled with `fill` (element_bytes each). rank_row = number of row dimensions.
namespace {
void CopyPadded(const unsigned char* src, const hsize_t* from, unsigned char* dst,
                const hsize_t* to, int rank_row, std::size_t element_bytes,
                const unsigned char* fill) {
  std::size_t total = element_bytes;
  for (int d = 0; d < rank_row; ++d) total *= to[d];
  for (std::size_t b = 0; b < total; b += element_bytes) std::memcpy(dst + b, fill, element_bytes);
  if (rank_row == 0) return std::memcpy(dst, src, element_bytes), void();
  std::array<hsize_t, FrameSeries::kMaxRank> idx{};
  const hsize_t run = from[rank_row - 1];
  while (true) {
    std::size_t s = 0, t = 0;
    for (int d = 0; d + 1 < rank_row; ++d) {
      s = s * from[d] + idx[d];
      t = t * to[d] + idx[d];
    }
    bool empty = false;
    for (int d = 0; d + 1 < rank_row; ++d) empty |= from[d] == 0;
    if (!empty && run > 0) {
      std::memcpy(dst + t * to[rank_row - 1] * element_bytes, src + s * run * element_bytes,
                  run * element_bytes);
    }
    int d = rank_row - 2;
    for (; d >= 0; --d) {
      if (++idx[d] < from[d]) break;
      idx[d] = 0;
    }
    if (d < 0) return;
  }
}
}  // namespace

void FrameSeries::Regrow(const hsize_t* row) {
  const std::size_t old_row = RowElements() * element_bytes_;
  std::array<hsize_t, kMaxRank> old = row_;
  for (int d = 1; d < rank_; ++d) row_[d] = std::max(row_[d], row[d - 1]);
  const std::size_t new_row = RowElements() * element_bytes_;
  const hsize_t n = frames_ - first_;
  regrow_.clear();
  regrow_.reserve(std::max<hsize_t>(n + 1, chunk_[0]) * new_row);  // as Create reserves
  regrow_.resize(n * new_row);
  for (hsize_t i = 0; i < n; ++i) {
    CopyPadded(buf_.data() + i * old_row, old.data() + 1, regrow_.data() + i * new_row,
               row_.data() + 1, rank_ - 1, element_bytes_, fill_.data());
  }
  buf_.swap(regrow_);
}

void FrameSeries::Write(std::initializer_list<hsize_t> row_count, const void* data) {
  if (static_cast<int>(row_count.size()) != rank_ - 1) {
    throw std::logic_error("FrameSeries::Write: row rank differs from " + ds_.path());
  }
  const hsize_t* count = row_count.begin();
  bool grows = false;
  for (int d = 1; d < rank_; ++d) grows |= count[d - 1] > row_[d];
  if (grows) Regrow(count);
  bool exact = true;
  for (int d = 1; d < rank_; ++d) exact &= count[d - 1] == row_[d];
  const std::size_t bytes = RowElements() * element_bytes_;
  const std::size_t at = buf_.size();
  buf_.resize(at + bytes);
  const auto* p = static_cast<const unsigned char*>(data);
  if (exact) {
    if (bytes > 0) std::memcpy(buf_.data() + at, p, bytes);  // an empty row may have no data
  } else {
    CopyPadded(p, count, buf_.data() + at, row_.data() + 1, rank_ - 1, element_bytes_,
               fill_.data());
  }
  ++frames_;
}

void FrameSeries::PushBytes(const void* value, std::size_t bytes) {
  if (rank_ != 1 || bytes != element_bytes_) {
    throw std::logic_error("FrameSeries::Push: not a scalar of this type: " + ds_.path());
  }
  const auto* p = static_cast<const unsigned char*>(value);
  buf_.insert(buf_.end(), p, p + bytes);
  ++frames_;
}

void FrameSeries::WriteChunks(hsize_t t0, hsize_t nt) {
  const int rr = rank_ - 1;  // row dimensions
  std::array<hsize_t, kMaxRank> grid{}, k{};
  for (int d = 1; d < rank_; ++d) {
    if (row_[d] == 0) return;  // no elements
    grid[d] = (row_[d] + chunk_[d] - 1) / chunk_[d];
  }
  std::size_t chunk_elements = 1;
  for (int d = 0; d < rank_; ++d) chunk_elements *= chunk_[d];
  const std::size_t row_bytes = RowElements() * element_bytes_;
  const std::size_t chunk_row_bytes = chunk_elements / chunk_[0] * element_bytes_;
  chunk_buf_.resize(chunk_elements * element_bytes_);
  while (true) {
    // The part of each buffered frame's row inside chunk k, copied into the chunk's row i.
    for (std::size_t b = 0; b < chunk_buf_.size(); b += element_bytes_) {
      std::memcpy(chunk_buf_.data() + b, fill_.data(), element_bytes_);
    }
    std::array<hsize_t, kMaxRank> part{};  // extent of the chunk inside the row shape
    for (int d = 1; d < rank_; ++d) part[d] = std::min(chunk_[d], row_[d] - k[d] * chunk_[d]);
    for (hsize_t i = 0; i < nt; ++i) {
      const unsigned char* row = buf_.data() + (t0 - first_ + i) * row_bytes;
      unsigned char* out = chunk_buf_.data() + i * chunk_row_bytes;
      if (rr == 0) {
        std::memcpy(out, row, element_bytes_);
        continue;
      }
      // Odometer over the chunk's row dimensions but the last; the last is one contiguous run.
      std::array<hsize_t, kMaxRank> j{};
      while (true) {
        std::size_t s = 0, t = 0;
        for (int d = 1; d < rank_; ++d) {
          const hsize_t at = d + 1 < rank_ ? j[d] : 0;
          s = s * row_[d] + k[d] * chunk_[d] + at;
          t = t * chunk_[d] + at;
        }
        std::memcpy(out + t * element_bytes_, row + s * element_bytes_,
                    part[rank_ - 1] * element_bytes_);
        int d = rank_ - 2;
        for (; d >= 1; --d) {
          if (++j[d] < part[d]) break;
          j[d] = 0;
        }
        if (d < 1) break;
      }
    }
    std::array<hsize_t, kMaxRank> offset{};
    offset[0] = t0;
    for (int d = 1; d < rank_; ++d) offset[d] = k[d] * chunk_[d];
    StoreChunkVia(queue_, codec_, ds_, rank_, offset.data(), chunk_buf_.data(), chunk_elements);
    int d = rank_ - 1;
    for (; d >= 1; --d) {
      if (++k[d] < grid[d]) break;
      k[d] = 0;
    }
    if (d < 1) return;
  }
}

void FrameSeries::WriteOut(bool partial) {
  const hsize_t c = chunk_[0];
  const hsize_t full = first_ + (frames_ - first_) / c * c;
  const hsize_t end = partial ? frames_ : full;
  bool rows_grew = false;
  for (int d = 1; d < rank_; ++d) rows_grew |= row_[d] != extent_[d];
  if (end <= first_ || (end <= extent_[0] && !rows_grew)) return;  // nothing new to store
  std::array<hsize_t, kMaxRank> dims = row_;
  dims[0] = std::max(end, extent_[0]);
  SetExtentVia(queue_, ds_, rank_, dims.data());
  extent_ = dims;
  for (hsize_t t0 = first_; t0 < end; t0 += c) WriteChunks(t0, std::min(c, end - t0));
  // Full chunks leave the buffer; a part-filled one stays (stored again once full).
  const std::size_t drop = (full - first_) * RowElements() * element_bytes_;
  buf_.erase(buf_.begin(), buf_.begin() + static_cast<std::ptrdiff_t>(drop));
  first_ = full;
}

// ---- RowSeries -------------------------------------------------------------------------------

void RowSeries::Create(h5::Group& g, const std::string& name, hid_t file_type, hid_t mem_type,
                       int columns, std::size_t row_bytes, int deflate, hsize_t chunk_rows) {
  row_bytes_ = row_bytes;
  columns_ = columns;
  std::vector<hsize_t> dims{0};
  std::size_t element_bytes = H5Tget_size(file_type);
  if (columns > 0) dims.push_back(static_cast<hsize_t>(columns));
  if (columns == 0) element_bytes = row_bytes;  // compound rows: chunked by their memory size
  h5::DatasetSpec spec = h5::GrowingSpec(dims, element_bytes);
  if (chunk_rows > 0) spec.chunk[0] = chunk_rows;
  chunk_rows_ = static_cast<std::int64_t>(spec.chunk[0]);
  spec.deflate = deflate;
  ds_ = g.CreateDataset(name, file_type, spec);
  codec_.Init(mem_type, file_type, deflate);
  pending_.reserve(static_cast<std::size_t>(chunk_rows_) * row_bytes_);
}

void RowSeries::Append(const void* data, std::int64_t rows) {
  if (rows <= 0) return;
  const auto* p = static_cast<const unsigned char*>(data);
  pending_.insert(pending_.end(), p, p + static_cast<std::size_t>(rows) * row_bytes_);
  total_ += rows;
  if (total_ - first_ >= chunk_rows_) StoreFullChunks();
}

void RowSeries::StoreFullChunks() {
  const std::int64_t full = first_ + (total_ - first_) / chunk_rows_ * chunk_rows_;
  if (full <= first_) return;
  if (full > extent_) {
    const hsize_t dims[2] = {static_cast<hsize_t>(full), static_cast<hsize_t>(columns_)};
    SetExtentVia(queue_, ds_, columns_ > 0 ? 2 : 1, dims);
    extent_ = full;
  }
  const std::size_t chunk_bytes = static_cast<std::size_t>(chunk_rows_) * row_bytes_;
  const std::size_t elements =
      static_cast<std::size_t>(chunk_rows_) * (columns_ > 0 ? columns_ : 1);
  std::size_t at = 0;
  for (std::int64_t r = first_; r < full; r += chunk_rows_, at += chunk_bytes) {
    const hsize_t offset[2] = {static_cast<hsize_t>(r), 0};
    StoreChunkVia(queue_, codec_, ds_, columns_ > 0 ? 2 : 1, offset, pending_.data() + at,
                  elements);
  }
  pending_.erase(pending_.begin(), pending_.begin() + static_cast<std::ptrdiff_t>(at));
  first_ = full;
}

void RowSeries::WriteOut(Tail tail) {
  if (tail == Tail::kKeep || total_ == first_) return;
  if (tail == Tail::kSeal) {
    const std::int64_t pad = chunk_rows_ - (total_ - first_);
    pending_.resize(pending_.size() + static_cast<std::size_t>(pad) * row_bytes_, 0);
    total_ += pad;
    return StoreFullChunks();
  }
  if (stored_tail_ == total_) return;  // stored as it is already
  const hsize_t dims[2] = {static_cast<hsize_t>(total_), static_cast<hsize_t>(columns_)};
  SetExtentVia(queue_, ds_, columns_ > 0 ? 2 : 1, dims);
  extent_ = total_;
  // A whole chunk's bytes: the rows beyond the extent are zeros.
  const std::size_t have = pending_.size();
  pending_.resize(static_cast<std::size_t>(chunk_rows_) * row_bytes_, 0);
  const hsize_t offset[2] = {static_cast<hsize_t>(first_), 0};
  StoreChunkVia(queue_, codec_, ds_, columns_ > 0 ? 2 : 1, offset, pending_.data(),
                static_cast<std::size_t>(chunk_rows_) * (columns_ > 0 ? columns_ : 1));
  pending_.resize(have);
  stored_tail_ = total_;
}

// ---- BlockSeries -----------------------------------------------------------------------------

void BlockSeries::Create(h5::Group& g, const std::string& name, hid_t file_type, hid_t mem_type,
                         int columns, std::size_t row_bytes, int deflate, hsize_t chunk_frames,
                         hsize_t chunk_rows) {
  row_bytes_ = row_bytes;
  data_.Create(g, name, file_type, mem_type, columns, row_bytes, deflate, chunk_rows);
  offset_.Create(g, layout::OffsetName(name), H5T_STD_I64LE, H5T_NATIVE_INT64, {}, {}, nullptr,
                 deflate, chunk_frames);
  count_.Create(g, layout::CountName(name), H5T_STD_I64LE, H5T_NATIVE_INT64, {}, {}, nullptr,
                deflate, chunk_frames);
}

void BlockSeries::Write(const void* data, std::int64_t rows) {
  const std::size_t bytes = static_cast<std::size_t>(rows) * row_bytes_;
  const bool same = has_last_ && last_.size() == bytes &&
                    (bytes == 0 || std::memcmp(last_.data(), data, bytes) == 0);
  if (!same) {
    const auto* p = static_cast<const unsigned char*>(data);
    last_.assign(p, p + bytes);
    has_last_ = true;
    last_offset_ = data_.total_rows();
    last_count_ = rows;
    data_.Append(data, rows);
  }
  offset_.Push(last_offset_);
  count_.Push(last_count_);
}

void BlockSeries::WriteOut(bool seal) {
  if (!seal) return;
  data_.WriteOut(RowSeries::Tail::kSeal);
  offset_.WriteOut(true);
  count_.WriteOut(true);
}

}  // namespace arthrosim::io::detail
