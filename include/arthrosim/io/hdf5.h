#pragma once
// A thin RAII layer over the HDF5 C API: just what run output needs (files with SWMR, groups,
// chunked extensible datasets, attributes, hyperslab read/write). The C++ API of HDF5 has no SWMR
// calls, hence our own. Every failure throws h5::Error naming the file and object path, with the
// innermost HDF5 message; HDF5's automatic error-stack printing is switched off.
#include <hdf5.h>

#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "arthrosim/core/hdf5_handle.h"

namespace arthrosim::io::h5 {

/// An HDF5 failure: "HDF5: <what> (file '<file>', object '<object>'): <library message>".
class Error : public std::runtime_error {
 public:
  Error(const std::string& file, const std::string& object, const std::string& what);
};

/// HDF5 memory type of T (not to be closed). Specialised for the arithmetic types we store.
template <class T>
hid_t NativeType();

/// The RAII owner of an HDF5 id (core/hdf5_handle.h).
using arthrosim::h5::Handle;

/// A group or dataset: something with a path that carries attributes.
class Object {
 public:
  hid_t id() const { return h_.get(); }
  const std::string& file() const { return file_; }
  const std::string& path() const { return path_; }
  bool valid() const { return h_.valid(); }

  /// Attribute writers (variable-length UTF-8 strings, float64, int64). Create or overwrite.
  void SetAttr(const std::string& name, const std::string& value);
  void SetAttr(const std::string& name, const char* value) { SetAttr(name, std::string(value)); }
  void SetAttr(const std::string& name, double value);
  void SetAttr(const std::string& name, std::int64_t value);
  void SetAttr(const std::string& name, int value) { SetAttr(name, std::int64_t{value}); }
  bool HasAttr(const std::string& name) const;
  /// Attribute readers; throw Error if absent or of another class.
  std::string AttrString(const std::string& name) const;
  double AttrDouble(const std::string& name) const;
  std::int64_t AttrInt(const std::string& name) const;

 protected:
  Object() = default;
  Object(Handle h, std::string file, std::string path)
      : h_(std::move(h)), file_(std::move(file)), path_(std::move(path)) {}
  /// Throws Error(file, path, what) if status < 0.
  void Check(std::int64_t status, const std::string& what) const;
  /// The same without building a std::string unless it fails (hot paths).
  void Check(std::int64_t status, const char* what) const;

  Handle h_;
  std::string file_;
  std::string path_;
};

/// Creation parameters of a dataset. Chunked when `chunk` is non-empty (required if any max
/// dimension is unlimited); shuffle + deflate when `deflate` > 0.
struct DatasetSpec {
  std::vector<hsize_t> dims;      ///< initial extent
  std::vector<hsize_t> max_dims;  ///< H5S_UNLIMITED for growable dimensions; empty = dims
  std::vector<hsize_t> chunk;     ///< chunk shape, same rank; empty = contiguous
  int deflate = 4;                ///< zlib level 0..9
  const void* fill = nullptr;     ///< fill value in the dataset's type, or nullptr for zeros
};

/// Chunks along a dimension listed in GrowingSpec's `also_grow`: its maximum extent. Kept small:
/// the extensible-array chunk index spans the maximum (1024 chunks per index page), so a large
/// one costs a page per few time chunks.
inline constexpr hsize_t kGrowChunks = 16;

/// Chunked, compressed spec for a dataset growing along dim 0 without bound (and along dims
/// listed in `also_grow` up to kGrowChunks chunks), initial extent `dims`. The chunk holds
/// whole rows and ~64 KiB at most per chunk unless one row alone is bigger (then one row,
/// capped at 1 MiB).
DatasetSpec GrowingSpec(std::vector<hsize_t> dims, std::size_t element_bytes,
                        std::vector<int> also_grow = {});

class Dataset : public Object {
 public:
  Dataset() = default;
  Dataset(Handle h, std::string file, std::string path)
      : Object(std::move(h), std::move(file), std::move(path)) {}

  /// Current extent.
  std::vector<hsize_t> dims() const;
  /// Grows (or shrinks) the extent; chunked datasets only.
  void SetExtent(const std::vector<hsize_t>& dims) {
    SetExtent(static_cast<int>(dims.size()), dims.data());
  }
  /// As above with `rank` entries at `dims` (no C++ heap allocation: the writer's block path).
  void SetExtent(int rank, const hsize_t* dims);
  /// Writes the hyperslab [start, start+count) from contiguous memory of type `mem_type`.
  void Write(const std::vector<hsize_t>& start, const std::vector<hsize_t>& count, hid_t mem_type,
             const void* data);
  /// As above with `rank` entries at `start` and `count` (no C++ heap allocation).
  void Write(int rank, const hsize_t* start, const hsize_t* count, hid_t mem_type,
             const void* data);
  /// Reads the hyperslab [start, start+count) into contiguous memory of type `mem_type`.
  void Read(const std::vector<hsize_t>& start, const std::vector<hsize_t>& count, hid_t mem_type,
            void* data) const;
  /// Stores one whole chunk as is (H5Dwrite_chunk): `bytes` bytes at `data`, already passed
  /// through the dataset's filters (`filter_mask` bit i set = filter i skipped), at the chunk
  /// whose first element is `offset` (rank entries, multiples of the chunk shape). Bypasses the
  /// chunk cache: under SWMR, HDF5 1.10 keeps every chunk that H5Dwrite wrote in memory until
  /// the file is closed.
  void WriteChunk(const hsize_t* offset, const void* data, std::size_t bytes,
                  std::uint32_t filter_mask = 0);
  /// Appends `rows` rows along dim 0; the other dimensions keep their current extent.
  void AppendRows(hid_t mem_type, const void* data, hsize_t rows);
  template <class T>
  void AppendRows(const T* data, hsize_t rows) {
    AppendRows(NativeType<T>(), data, rows);
  }
  /// Whole dataset, flattened row-major.
  template <class T>
  std::vector<T> ReadAll() const {
    const std::vector<hsize_t> d = dims();
    std::size_t n = 1;
    for (hsize_t x : d) n *= x;
    std::vector<T> out(n);
    if (n > 0) Read(std::vector<hsize_t>(d.size(), 0), d, NativeType<T>(), out.data());
    return out;
  }
  /// A scalar variable-length string dataset's value.
  std::string ReadString() const;
  /// Re-reads metadata written by a SWMR writer since the file was opened.
  void Refresh();
  /// Flushes this dataset's data and metadata to the file (SWMR writer).
  void Flush();
};

class Group : public Object {
 public:
  Group() = default;
  Group(Handle h, std::string file, std::string path)
      : Object(std::move(h), std::move(file), std::move(path)) {}

  Group CreateGroup(const std::string& name);
  Group OpenGroup(const std::string& name) const;
  /// Whether a link `name` (relative path allowed) exists below this group.
  bool Exists(const std::string& name) const;
  /// Names of the direct children, in HDF5's (alphabetical) order.
  std::vector<std::string> Children() const;
  Dataset CreateDataset(const std::string& name, hid_t file_type, const DatasetSpec& spec);
  template <class T>
  Dataset CreateDataset(const std::string& name, const DatasetSpec& spec) {
    return CreateDataset(name, NativeType<T>(), spec);
  }
  /// A scalar variable-length UTF-8 string dataset.
  Dataset CreateStringDataset(const std::string& name, const std::string& value);
  /// Opens a dataset; `chunk_cache_bytes` > 0 sets its raw-data chunk cache.
  Dataset OpenDataset(const std::string& name, std::size_t chunk_cache_bytes = 0) const;

 private:
  std::string Child(const std::string& name) const;
};

class File {
 public:
  File() = default;
  /// Creates (truncates) `path` with the latest file format, as SWMR requires.
  static File Create(const std::string& path);
  /// Opens read-only; with `swmr` also while a SWMR writer has it open (or after it crashed).
  static File OpenReadOnly(const std::string& path, bool swmr);

  Group& root() { return root_; }
  const Group& root() const { return root_; }
  const std::string& path() const { return path_; }
  bool is_open() const { return handle_.valid(); }
  /// Switches to single-writer/multiple-reader mode: no object may be created afterwards.
  void StartSwmrWrite();
  /// Writes every cached change to disk.
  void Flush();
  /// Closes every object of the file (groups/datasets held elsewhere must be closed first).
  void Close();

 private:
  Handle handle_;
  Group root_;
  std::string path_;
};

/// Turns off HDF5's printing of its error stack on this thread (we report via exceptions).
void SilenceErrorStack();
/// The HDF5 library version, e.g. "1.10.8".
std::string LibraryVersion();

}  // namespace arthrosim::io::h5
