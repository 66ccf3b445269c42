#include "arthrosim/io/hdf5.h"

#include <algorithm>

namespace arthrosim::io::h5 {
namespace {

// Keeps the innermost message of the error stack (walking upward it comes first): it names
// the real cause, e.g. "unable to open file: ... errno = 2 ...".
herr_t WalkError(unsigned n, const H5E_error2_t* err, void* out) {
  auto* msg = static_cast<std::string*>(out);
  if (n == 0 && err->desc != nullptr) *msg = err->desc;
  return 0;
}

std::string LibraryMessage() {
  std::string msg;
  H5Ewalk2(H5E_DEFAULT, H5E_WALK_UPWARD, WalkError, &msg);
  H5Eclear2(H5E_DEFAULT);
  return msg;
}

[[noreturn]] void Fail(const std::string& file, const std::string& object,
                       const std::string& what) {
  throw Error(file, object, what);
}

Handle Ok(hid_t id, herr_t (*close)(hid_t), const std::string& file, const std::string& object,
          const std::string& what) {
  if (id < 0) Fail(file, object, what);
  return Handle(id, close);
}

Handle VlenStringType() {
  Handle t(H5Tcopy(H5T_C_S1), H5Tclose);
  H5Tset_size(t.get(), H5T_VARIABLE);
  H5Tset_cset(t.get(), H5T_CSET_UTF8);
  return t;
}

}  // namespace

Error::Error(const std::string& file, const std::string& object, const std::string& what)
    : std::runtime_error([&] {
        std::string s = "HDF5: " + what + " (file '" + file + "'";
        if (!object.empty()) s += ", object '" + object + "'";
        s += ")";
        const std::string lib = LibraryMessage();
        if (!lib.empty()) s += ": " + lib;
        return s;
      }()) {}

template <>
hid_t NativeType<double>() {
  return H5T_NATIVE_DOUBLE;
}
template <>
hid_t NativeType<float>() {
  return H5T_NATIVE_FLOAT;
}
template <>
hid_t NativeType<std::int8_t>() {
  return H5T_NATIVE_INT8;
}
template <>
hid_t NativeType<std::uint8_t>() {
  return H5T_NATIVE_UINT8;
}
template <>
hid_t NativeType<std::int32_t>() {
  return H5T_NATIVE_INT32;
}
template <>
hid_t NativeType<std::int64_t>() {
  return H5T_NATIVE_INT64;
}
template <>
hid_t NativeType<std::uint64_t>() {
  return H5T_NATIVE_UINT64;
}

void SilenceErrorStack() {
  thread_local bool silenced = false;
  if (!silenced) {
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
    silenced = true;
  }
}

std::string LibraryVersion() {
  unsigned maj = 0, min = 0, rel = 0;
  H5get_libversion(&maj, &min, &rel);
  return std::to_string(maj) + "." + std::to_string(min) + "." + std::to_string(rel);
}

// ---- Handle ----------------------------------------------------------------------------------

// ---- Object: attributes ---------------------------------------------------------------------

void Object::Check(std::int64_t status, const std::string& what) const {
  if (status < 0) Fail(file_, path_, what);
}

void Object::Check(std::int64_t status, const char* what) const {
  if (status < 0) Fail(file_, path_, what);
}

namespace {
// Opens attribute `name` for writing, replacing an existing one of another type.
Handle CreateAttr(const Object& o, const std::string& name, hid_t type) {
  if (H5Aexists(o.id(), name.c_str()) > 0) H5Adelete(o.id(), name.c_str());
  Handle space(H5Screate(H5S_SCALAR), H5Sclose);
  return Ok(H5Acreate2(o.id(), name.c_str(), type, space.get(), H5P_DEFAULT, H5P_DEFAULT), H5Aclose,
            o.file(), o.path(), "cannot create attribute '" + name + "'");
}
Handle OpenAttr(const Object& o, const std::string& name) {
  return Ok(H5Aopen(o.id(), name.c_str(), H5P_DEFAULT), H5Aclose, o.file(), o.path(),
            "missing attribute '" + name + "'");
}
}  // namespace

void Object::SetAttr(const std::string& name, const std::string& value) {
  Handle type = VlenStringType();
  Handle a = CreateAttr(*this, name, type.get());
  const char* p = value.c_str();
  Check(H5Awrite(a.get(), type.get(), &p), "cannot write attribute '" + name + "'");
}

void Object::SetAttr(const std::string& name, double value) {
  Handle a = CreateAttr(*this, name, H5T_IEEE_F64LE);
  Check(H5Awrite(a.get(), H5T_NATIVE_DOUBLE, &value), "cannot write attribute '" + name + "'");
}

void Object::SetAttr(const std::string& name, std::int64_t value) {
  Handle a = CreateAttr(*this, name, H5T_STD_I64LE);
  Check(H5Awrite(a.get(), H5T_NATIVE_INT64, &value), "cannot write attribute '" + name + "'");
}

bool Object::HasAttr(const std::string& name) const { return H5Aexists(id(), name.c_str()) > 0; }

std::string Object::AttrString(const std::string& name) const {
  Handle a = OpenAttr(*this, name);
  Handle ftype(H5Aget_type(a.get()), H5Tclose);
  if (H5Tget_class(ftype.get()) != H5T_STRING) {
    Fail(file_, path_, "attribute '" + name + "' is not a string");
  }
  if (H5Tis_variable_str(ftype.get()) > 0) {
    Handle mtype = VlenStringType();
    char* p = nullptr;
    Check(H5Aread(a.get(), mtype.get(), &p), "cannot read attribute '" + name + "'");
    std::string s = p != nullptr ? p : "";
    H5free_memory(p);
    return s;
  }
  const std::size_t n = H5Tget_size(ftype.get());
  std::string s(n, '\0');
  Check(H5Aread(a.get(), ftype.get(), s.data()), "cannot read attribute '" + name + "'");
  s.resize(std::min(s.size(), s.find('\0')));
  return s;
}

double Object::AttrDouble(const std::string& name) const {
  Handle a = OpenAttr(*this, name);
  double v = 0;
  Check(H5Aread(a.get(), H5T_NATIVE_DOUBLE, &v), "cannot read attribute '" + name + "'");
  return v;
}

std::int64_t Object::AttrInt(const std::string& name) const {
  Handle a = OpenAttr(*this, name);
  std::int64_t v = 0;
  Check(H5Aread(a.get(), H5T_NATIVE_INT64, &v), "cannot read attribute '" + name + "'");
  return v;
}

// ---- Dataset --------------------------------------------------------------------------------

DatasetSpec GrowingSpec(std::vector<hsize_t> dims, std::size_t element_bytes,
                        std::vector<int> also_grow) {
  DatasetSpec s;
  s.dims = dims;
  s.max_dims = dims;
  s.max_dims[0] = H5S_UNLIMITED;
  s.chunk = dims;
  std::size_t row_bytes = element_bytes;
  for (std::size_t d = 1; d < dims.size(); ++d) {
    s.chunk[d] = std::max<hsize_t>(dims[d], 1);
    row_bytes *= s.chunk[d];
  }
  // Cap one row at 1 MiB along dim 1 (the node / element dimension).
  constexpr std::size_t kMaxRow = std::size_t{1} << 20;
  if (row_bytes > kMaxRow && dims.size() > 1) {
    const std::size_t per_dim1 = row_bytes / s.chunk[1];
    s.chunk[1] = std::max<hsize_t>(1, kMaxRow / per_dim1);
    row_bytes = per_dim1 * s.chunk[1];
  }
  constexpr std::size_t kTarget = std::size_t{64} << 10;
  s.chunk[0] = std::clamp<hsize_t>(kTarget / row_bytes, 1, 4096);
  // The other growing dimensions get a finite maximum (kGrowChunks chunks): with one unlimited
  // dimension HDF5 indexes chunks with an extensible array; with two, with a v2 B-tree whose
  // nodes a SWMR writer rewrites elsewhere at every flush, never reusing the old space (~4 kB
  // per dataset and flush).
  for (int d : also_grow) {
    const auto k = static_cast<std::size_t>(d);
    s.max_dims[k] = std::max(s.chunk[k] * kGrowChunks, s.dims[k]);
  }
  return s;
}

std::vector<hsize_t> Dataset::dims() const {
  Handle space(H5Dget_space(id()), H5Sclose);
  Check(space.get(), "cannot get dataspace");
  const int rank = H5Sget_simple_extent_ndims(space.get());
  Check(rank, "cannot get rank");
  std::vector<hsize_t> d(static_cast<std::size_t>(rank));
  H5Sget_simple_extent_dims(space.get(), d.data(), nullptr);
  return d;
}

void Dataset::SetExtent(int rank, const hsize_t* dims) {
  Handle space(H5Dget_space(id()), H5Sclose);
  if (!space.valid() || H5Sget_simple_extent_ndims(space.get()) != rank) {
    Fail(file_, path_, "extent rank does not match the dataset");
  }
  Check(H5Dset_extent(id(), dims), "cannot change extent");
}

namespace {
Handle SelectSlab(const Dataset& d, int rank, const hsize_t* start, const hsize_t* count) {
  Handle space(H5Dget_space(d.id()), H5Sclose);
  if (!space.valid() || H5Sget_simple_extent_ndims(space.get()) != rank) {
    throw Error(d.file(), d.path(), "hyperslab rank does not match the dataset");
  }
  if (H5Sselect_hyperslab(space.get(), H5S_SELECT_SET, start, nullptr, count, nullptr) < 0) {
    throw Error(d.file(), d.path(), "bad hyperslab");
  }
  return space;
}
}  // namespace

void Dataset::Write(const std::vector<hsize_t>& start, const std::vector<hsize_t>& count,
                    hid_t mem_type, const void* data) {
  if (start.size() != count.size()) Fail(file_, path_, "hyperslab rank does not match the dataset");
  Write(static_cast<int>(count.size()), start.data(), count.data(), mem_type, data);
}

void Dataset::Write(int rank, const hsize_t* start, const hsize_t* count, hid_t mem_type,
                    const void* data) {
  for (int d = 0; d < rank; ++d) {
    if (count[d] == 0) return;
  }
  Handle fspace = SelectSlab(*this, rank, start, count);
  Handle mspace(H5Screate_simple(rank, count, nullptr), H5Sclose);
  Check(H5Dwrite(id(), mem_type, mspace.get(), fspace.get(), H5P_DEFAULT, data), "cannot write");
}

void Dataset::WriteChunk(const hsize_t* offset, const void* data, std::size_t bytes,
                         std::uint32_t filter_mask) {
  Check(H5Dwrite_chunk(id(), H5P_DEFAULT, filter_mask, offset, bytes, data), "cannot write chunk");
}

void Dataset::Read(const std::vector<hsize_t>& start, const std::vector<hsize_t>& count,
                   hid_t mem_type, void* data) const {
  for (hsize_t c : count) {
    if (c == 0) return;
  }
  if (start.size() != count.size()) Fail(file_, path_, "hyperslab rank does not match the dataset");
  Handle fspace = SelectSlab(*this, static_cast<int>(count.size()), start.data(), count.data());
  Handle mspace(H5Screate_simple(static_cast<int>(count.size()), count.data(), nullptr), H5Sclose);
  Check(H5Dread(id(), mem_type, mspace.get(), fspace.get(), H5P_DEFAULT, data), "cannot read");
}

void Dataset::AppendRows(hid_t mem_type, const void* data, hsize_t rows) {
  if (rows == 0) return;
  std::vector<hsize_t> d = dims();
  std::vector<hsize_t> start(d.size(), 0);
  start[0] = d[0];
  d[0] += rows;
  SetExtent(d);
  std::vector<hsize_t> count = d;
  count[0] = rows;
  Write(start, count, mem_type, data);
}

std::string Dataset::ReadString() const {
  Handle mtype = VlenStringType();
  char* p = nullptr;
  Check(H5Dread(id(), mtype.get(), H5S_ALL, H5S_ALL, H5P_DEFAULT, &p), "cannot read string");
  std::string s = p != nullptr ? p : "";
  H5free_memory(p);
  return s;
}

void Dataset::Refresh() { Check(H5Drefresh(id()), "cannot refresh"); }

void Dataset::Flush() { Check(H5Dflush(id()), "cannot flush"); }

// ---- Group ----------------------------------------------------------------------------------

std::string Group::Child(const std::string& name) const {
  return path_ == "/" ? "/" + name : path_ + "/" + name;
}

namespace {
// Objects are created without access/modification/change times in their headers (HDF5 stores
// them by default and updates the modification time whenever an extent grows): the same frames
// make the same file bytes, whenever and however fast they were written (but /meta's created_utc).
Handle UntimedCreation(hid_t cls) {
  Handle plist(H5Pcreate(cls), H5Pclose);
  H5Pset_obj_track_times(plist.get(), false);
  return plist;
}
}  // namespace

Group Group::CreateGroup(const std::string& name) {
  const std::string p = Child(name);
  const Handle gcpl = UntimedCreation(H5P_GROUP_CREATE);
  return Group(Ok(H5Gcreate2(id(), name.c_str(), H5P_DEFAULT, gcpl.get(), H5P_DEFAULT), H5Gclose,
                  file_, p, "cannot create group"),
               file_, p);
}

Group Group::OpenGroup(const std::string& name) const {
  const std::string p = Child(name);
  return Group(
      Ok(H5Gopen2(id(), name.c_str(), H5P_DEFAULT), H5Gclose, file_, p, "cannot open group"), file_,
      p);
}

bool Group::Exists(const std::string& name) const {
  // H5Lexists needs every intermediate link to exist: check component by component.
  std::size_t pos = 0;
  while (true) {
    const std::size_t slash = name.find('/', pos);
    const std::string prefix = name.substr(0, slash);
    if (H5Lexists(id(), prefix.c_str(), H5P_DEFAULT) <= 0) return false;
    if (slash == std::string::npos) return true;
    pos = slash + 1;
  }
}

std::vector<std::string> Group::Children() const {
  H5G_info_t info;
  Check(H5Gget_info(id(), &info), "cannot list group");
  std::vector<std::string> names;
  for (hsize_t i = 0; i < info.nlinks; ++i) {
    const ssize_t n =
        H5Lget_name_by_idx(id(), ".", H5_INDEX_NAME, H5_ITER_INC, i, nullptr, 0, H5P_DEFAULT);
    Check(n, "cannot list group");
    std::string s(static_cast<std::size_t>(n) + 1, '\0');
    H5Lget_name_by_idx(id(), ".", H5_INDEX_NAME, H5_ITER_INC, i, s.data(), s.size(), H5P_DEFAULT);
    s.resize(static_cast<std::size_t>(n));
    names.push_back(std::move(s));
  }
  return names;
}

Dataset Group::CreateDataset(const std::string& name, hid_t file_type, const DatasetSpec& spec) {
  const std::string p = Child(name);
  const std::vector<hsize_t>& maxd = spec.max_dims.empty() ? spec.dims : spec.max_dims;
  Handle space(H5Screate_simple(static_cast<int>(spec.dims.size()), spec.dims.data(), maxd.data()),
               H5Sclose);
  if (!space.valid()) Fail(file_, p, "bad dataset shape");
  Handle dcpl = UntimedCreation(H5P_DATASET_CREATE);
  if (!spec.chunk.empty()) {
    Check(H5Pset_chunk(dcpl.get(), static_cast<int>(spec.chunk.size()), spec.chunk.data()),
          "bad chunk shape for " + p);
    if (spec.deflate > 0) {
      H5Pset_shuffle(dcpl.get());
      H5Pset_deflate(dcpl.get(), static_cast<unsigned>(spec.deflate));
    }
  }
  if (spec.fill != nullptr) {
    Check(H5Pset_fill_value(dcpl.get(), file_type, spec.fill), "bad fill value for " + p);
  }
  // Raw-data chunk cache of two chunks (fully written chunks evicted first): enough to keep the
  // part-filled chunk a growing dataset appends to, and a bound on memory. HDF5's default, 1 MiB
  // per dataset, fills up with finished chunks over a long run (~150 datasets: ~150 MB).
  Handle dapl(H5Pcreate(H5P_DATASET_ACCESS), H5Pclose);
  if (!spec.chunk.empty()) {
    std::size_t chunk_bytes = H5Tget_size(file_type);
    for (hsize_t c : spec.chunk) chunk_bytes *= static_cast<std::size_t>(c);
    H5Pset_chunk_cache(dapl.get(), 13, 2 * chunk_bytes, 1.0);
  }
  return Dataset(Ok(H5Dcreate2(id(), name.c_str(), file_type, space.get(), H5P_DEFAULT, dcpl.get(),
                               dapl.get()),
                    H5Dclose, file_, p, "cannot create dataset"),
                 file_, p);
}

Dataset Group::CreateStringDataset(const std::string& name, const std::string& value) {
  const std::string p = Child(name);
  Handle type = VlenStringType();
  Handle space(H5Screate(H5S_SCALAR), H5Sclose);
  const Handle dcpl = UntimedCreation(H5P_DATASET_CREATE);
  Dataset d(Ok(H5Dcreate2(id(), name.c_str(), type.get(), space.get(), H5P_DEFAULT, dcpl.get(),
                          H5P_DEFAULT),
               H5Dclose, file_, p, "cannot create dataset"),
            file_, p);
  const char* s = value.c_str();
  if (H5Dwrite(d.id(), type.get(), H5S_ALL, H5S_ALL, H5P_DEFAULT, &s) < 0) {
    Fail(file_, p, "cannot write string");
  }
  return d;
}

Dataset Group::OpenDataset(const std::string& name, std::size_t chunk_cache_bytes) const {
  const std::string p = Child(name);
  Handle dapl(H5Pcreate(H5P_DATASET_ACCESS), H5Pclose);
  if (chunk_cache_bytes > 0) {
    H5Pset_chunk_cache(dapl.get(), 1021, chunk_cache_bytes, 0.75);
  }
  return Dataset(
      Ok(H5Dopen2(id(), name.c_str(), dapl.get()), H5Dclose, file_, p, "cannot open dataset"),
      file_, p);
}

// ---- File -----------------------------------------------------------------------------------

namespace {
Handle FileAccess() {
  Handle fapl(H5Pcreate(H5P_FILE_ACCESS), H5Pclose);
  H5Pset_libver_bounds(fapl.get(), H5F_LIBVER_LATEST, H5F_LIBVER_LATEST);
  // Closing the file closes every object still open in it: Close() really closes.
  H5Pset_fclose_degree(fapl.get(), H5F_CLOSE_STRONG);
  return fapl;
}

// A writer's metadata cache of a small fixed size (256 KiB). HDF5's adaptive default grows it
// toward 32 MiB as the chunk indexes of a long run grow; at a fixed 2 MiB it still filled with the
// index blocks of every dataset (16 bytes per chunk, ~150 datasets, a chunk per dataset and
// flush), which the writer, appending, never reads again: +2.1 MB over 18 000 frames of the test
// model, still growing at 80 000 (RunMemory.WriterMemoryDoesNotGrowWithFrames). With 256 KiB
// they are evicted once written (+0.9 MB), and with HDF5's free lists bounded (below) their
// memory is reused (+0.5 MB). The writer's flushes run on its own thread.
void FixMetadataCache(hid_t fapl) {
  // HDF5 keeps freed blocks on free lists of its own, up to 1-16 MiB per kind by default, never
  // returned while the process runs: 64 KiB in all per kind, 16 KiB per list (process-wide).
  H5set_free_list_limits(64 << 10, 16 << 10, 64 << 10, 16 << 10, 64 << 10, 16 << 10);
  H5AC_cache_config_t c;
  c.version = H5AC__CURR_CACHE_CONFIG_VERSION;
  if (H5Pget_mdc_config(fapl, &c) < 0) return;
  c.set_initial_size = true;
  c.initial_size = std::size_t{256} << 10;
  c.min_size = c.initial_size;
  c.max_size = c.initial_size;
  c.incr_mode = H5C_incr__off;
  c.flash_incr_mode = H5C_flash_incr__off;
  c.decr_mode = H5C_decr__off;
  H5Pset_mdc_config(fapl, &c);
}
}  // namespace

File File::Create(const std::string& path) {
  SilenceErrorStack();
  File f;
  f.path_ = path;
  Handle fapl = FileAccess();
  FixMetadataCache(fapl.get());
  const Handle fcpl = UntimedCreation(H5P_FILE_CREATE);  // the root group's header too
  f.handle_ = Ok(H5Fcreate(path.c_str(), H5F_ACC_TRUNC, fcpl.get(), fapl.get()), H5Fclose, path, "",
                 "cannot create file");
  f.root_ = Group(Ok(H5Gopen2(f.handle_.get(), "/", H5P_DEFAULT), H5Gclose, path, "/",
                     "cannot open root group"),
                  path, "/");
  return f;
}

File File::OpenReadOnly(const std::string& path, bool swmr) {
  SilenceErrorStack();
  File f;
  f.path_ = path;
  Handle fapl = FileAccess();
  const unsigned flags = H5F_ACC_RDONLY | (swmr ? H5F_ACC_SWMR_READ : 0u);
  f.handle_ = Ok(H5Fopen(path.c_str(), flags, fapl.get()), H5Fclose, path, "",
                 "cannot open file for reading");
  f.root_ = Group(Ok(H5Gopen2(f.handle_.get(), "/", H5P_DEFAULT), H5Gclose, path, "/",
                     "cannot open root group"),
                  path, "/");
  return f;
}

void File::StartSwmrWrite() {
  if (H5Fstart_swmr_write(handle_.get()) < 0) Fail(path_, "", "cannot start SWMR write");
}

void File::Flush() {
  if (H5Fflush(handle_.get(), H5F_SCOPE_GLOBAL) < 0) Fail(path_, "", "cannot flush");
}

void File::Close() {
  root_ = Group();
  if (!handle_.valid()) return;
  const hid_t id = handle_.get();
  const herr_t status = H5Fclose(id);
  handle_ = Handle();  // already closed (or unusable): forget it without closing again
  if (status < 0) Fail(path_, "", "cannot close file");
}

}  // namespace arthrosim::io::h5
