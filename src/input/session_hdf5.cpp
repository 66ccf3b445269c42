// Session HDF5 reader and writer: one group per device (/slot0, /slot1, /scope) holding
// parallel datasets, docs/trajectory-format.md.
#include <fmt/format.h>
#include <hdf5.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

#include "arthrosim/core/error.h"
#include "arthrosim/core/hdf5_handle.h"
#include "arthrosim/input/session.h"

namespace arthrosim::input {
namespace {

using h5::Handle;

/// Silences HDF5's automatic error printing for the lifetime of the guard.
struct QuietHdf5 {
  H5E_auto2_t func = nullptr;
  void* data = nullptr;
  QuietHdf5() {
    H5Eget_auto2(H5E_DEFAULT, &func, &data);
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  }
  ~QuietHdf5() { H5Eset_auto2(H5E_DEFAULT, func, data); }
};

class Reader {
 public:
  Reader(const std::string& file, hid_t group, std::string group_name)
      : file_(file), group_(group), name_(std::move(group_name)) {}

  bool Has(const char* ds) const { return H5Lexists(group_, ds, H5P_DEFAULT) > 0; }

  /// Reads a float64 dataset of shape [n] (cols = 0) or [n, cols]; sets n on first call.
  std::vector<double> Doubles(const char* ds, int cols, hsize_t* n) const {
    Handle d(H5Dopen2(group_, ds, H5P_DEFAULT), H5Dclose);
    if (d.get() < 0) Fail(ds, 0, "missing dataset");
    Handle space(H5Dget_space(d.get()), H5Sclose);
    hsize_t dims[2] = {0, 0};
    const int want_rank = cols == 0 ? 1 : 2;
    // The rank first: dims has room for two.
    if (H5Sget_simple_extent_ndims(space.get()) != want_rank ||
        H5Sget_simple_extent_dims(space.get(), dims, nullptr) != want_rank ||
        (cols > 0 && dims[1] != static_cast<hsize_t>(cols))) {
      Fail(ds, 0,
           cols == 0 ? "expected a 1-D dataset" : fmt::format("expected shape [n, {}]", cols));
    }
    CheckRows(ds, dims[0], n);
    CheckStored(ds, d.get(), dims[0], static_cast<hsize_t>(std::max(cols, 1)));
    std::vector<double> v(dims[0] * std::max(cols, 1));
    if (!v.empty() &&
        H5Dread(d.get(), H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data()) < 0) {
      Fail(ds, 0, "cannot read as float64");
    }
    for (std::size_t i = 0; i < v.size(); ++i) {
      if (!std::isfinite(v[i])) {
        Fail(
            ds, static_cast<int>(i / std::max(cols, 1)) + 1,
            cols > 0 ? fmt::format("non-finite value in column {}", i % cols) : "non-finite value");
      }
    }
    return v;
  }

  std::vector<std::string> Strings(const char* ds, hsize_t* n) const {
    Handle d(H5Dopen2(group_, ds, H5P_DEFAULT), H5Dclose);
    if (d.get() < 0) Fail(ds, 0, "missing dataset");
    Handle ftype(H5Dget_type(d.get()), H5Tclose);
    if (H5Tget_class(ftype.get()) != H5T_STRING) Fail(ds, 0, "expected a string dataset");
    hsize_t dims[1] = {0};
    const Handle space = OneDimSpace(ds, d.get(), n, dims);
    std::vector<std::string> out(dims[0]);
    if (dims[0] == 0) return out;
    if (H5Tis_variable_str(ftype.get()) > 0) {
      Handle mtype(H5Tcopy(H5T_C_S1), H5Tclose);
      H5Tset_size(mtype.get(), H5T_VARIABLE);
      std::vector<char*> p(dims[0], nullptr);
      if (H5Dread(d.get(), mtype.get(), H5S_ALL, H5S_ALL, H5P_DEFAULT, p.data()) < 0) {
        Fail(ds, 0, "cannot read strings");
      }
      for (hsize_t i = 0; i < dims[0]; ++i) out[i] = p[i] ? p[i] : "";
      H5Dvlen_reclaim(mtype.get(), space.get(), H5P_DEFAULT, p.data());
    } else {
      const std::size_t len = H5Tget_size(ftype.get());
      Handle mtype(H5Tcopy(H5T_C_S1), H5Tclose);
      H5Tset_size(mtype.get(), len);
      H5Tset_strpad(mtype.get(), H5T_STR_NULLPAD);
      std::vector<char> buf(len * dims[0], '\0');
      if (H5Dread(d.get(), mtype.get(), H5S_ALL, H5S_ALL, H5P_DEFAULT, buf.data()) < 0) {
        Fail(ds, 0, "cannot read strings");
      }
      for (hsize_t i = 0; i < dims[0]; ++i) {
        const char* s = buf.data() + i * len;
        out[i] = std::string(s, strnlen(s, len));
      }
    }
    return out;
  }

  std::vector<std::uint8_t> Bytes(const char* ds, hsize_t* n) const {
    Handle d(H5Dopen2(group_, ds, H5P_DEFAULT), H5Dclose);
    if (d.get() < 0) Fail(ds, 0, "missing dataset");
    hsize_t dims[1] = {0};
    OneDimSpace(ds, d.get(), n, dims);
    std::vector<std::int64_t> v(dims[0]);
    if (!v.empty() &&
        H5Dread(d.get(), H5T_NATIVE_INT64, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data()) < 0) {
      Fail(ds, 0, "cannot read as integers");
    }
    std::vector<std::uint8_t> out(v.size());
    for (std::size_t i = 0; i < v.size(); ++i) {
      if (v[i] < 0 || v[i] > 3) Fail(ds, static_cast<int>(i) + 1, "buttons outside 0..3");
      out[i] = static_cast<std::uint8_t>(v[i]);
    }
    return out;
  }

  // The dataspace of dataset `ds` (open as d), which must be 1-D; dims[0]: its length, checked
  // against *n (CheckRows).
  Handle OneDimSpace(const char* ds, hid_t d, hsize_t* n, hsize_t dims[1]) const {
    Handle space(H5Dget_space(d), H5Sclose);
    if (H5Sget_simple_extent_ndims(space.get()) != 1 ||
        H5Sget_simple_extent_dims(space.get(), dims, nullptr) != 1) {
      Fail(ds, 0, "expected a 1-D dataset");
    }
    CheckRows(ds, dims[0], n);
    CheckStored(ds, d, dims[0], 1);
    return space;
  }

  [[noreturn]] void Fail(const char* ds, int row, const std::string& msg) const {
    throw InputError(file_, row, "/" + name_ + "/" + ds,
                     row > 0 ? fmt::format("row {}: {}", row, msg) : msg);
  }

 private:
  void CheckRows(const char* ds, hsize_t rows, hsize_t* n) const {
    if (*n == static_cast<hsize_t>(-1)) {
      *n = rows;
    } else if (rows != *n) {
      Fail(ds, 0, fmt::format("has {} rows but /{}/t has {}", rows, name_, *n));
    }
  }
  // Refuses a dataset d of rows x cols values whose data is kept outside the file (external raw
  // data files, virtual datasets: they can name any path, /dev/zero or a FIFO included), or
  // that declares more data than its stored bytes can hold, even compressed (deflate expands at
  // most ~1032:1), plus 64 KiB of fill value: a file of a few hundred bytes may declare
  // terabytes that reading would allocate.
  void CheckStored(const char* ds, hid_t d, hsize_t rows, hsize_t cols) const {
    const Handle dcpl(H5Dget_create_plist(d), H5Pclose);
    if (dcpl.get() < 0 || H5Pget_external_count(dcpl.get()) != 0 ||
        H5Pget_layout(dcpl.get()) == H5D_VIRTUAL) {
      Fail(ds, 0, "data stored outside the file (an external or virtual dataset) is not supported");
    }
    constexpr hsize_t kMaxExpansion = 1032, kFillBytes = 64 * 1024;
    const Handle type(H5Dget_type(d), H5Tclose);
    const hsize_t value_bytes = std::max<hsize_t>(1, H5Tget_size(type.get()));
    const hsize_t stored = H5Dget_storage_size(d);
    const hsize_t max_bytes = stored > (hsize_t{1} << 50) ? std::numeric_limits<hsize_t>::max()
                                                          : stored * kMaxExpansion + kFillBytes;
    if (rows > max_bytes / value_bytes / cols) {
      Fail(ds, 0,
           fmt::format("declares {} rows but the file stores only {} bytes of them (a damaged or "
                       "hand-made file)",
                       rows, stored));
    }
  }
  const std::string& file_;
  hid_t group_;
  std::string name_;
};

template <class T>
void WriteDataset(const std::string& path, hid_t group, const char* name, hid_t mem_type,
                  hid_t file_type, const std::vector<T>& data, hsize_t rows, hsize_t cols) {
  hsize_t dims[2] = {rows, cols};
  Handle space(H5Screate_simple(cols == 0 ? 1 : 2, dims, nullptr), H5Sclose);
  Handle d(H5Dcreate2(group, name, file_type, space.get(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT),
           H5Dclose);
  if (d.get() < 0 ||
      (rows > 0 && H5Dwrite(d.get(), mem_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, data.data()) < 0)) {
    throw InputError(path, 0, name, "cannot write HDF5 dataset");
  }
}

// The session in the HDF5 file `file_id` (closed here; < 0 if it could not be opened); `path`
// names it in messages. The caller holds a QuietHdf5.
SessionTable ReadOpenSession(hid_t file_id, const std::string& path,
                             const SessionOptions& options) {
  const Handle file(file_id, H5Fclose);
  if (file.get() < 0) throw InputError(path, 0, "", "cannot open as an HDF5 file");
  SessionTable table;
  table.file = path;
  std::vector<std::vector<SessionRow>> per_device(kDeviceCount);
  bool any = false;
  for (int d = 0; d < kDeviceCount; ++d) {
    const Device dev = static_cast<Device>(d);
    const char* name = DeviceName(dev);
    if (H5Lexists(file.get(), name, H5P_DEFAULT) <= 0) continue;
    Handle group(H5Gopen2(file.get(), name, H5P_DEFAULT), H5Gclose);
    if (group.get() < 0) throw InputError(path, 0, std::string("/") + name, "expected a group");
    any = true;
    Reader rd(path, group.get(), name);
    hsize_t n = static_cast<hsize_t>(-1);
    const std::vector<double> t = rd.Doubles("t", 0, &n);
    const std::vector<double> p = rd.Doubles("position", 3, &n);
    const std::vector<double> q = rd.Doubles("orientation", 4, &n);
    const bool scope = dev == Device::kScope;
    std::vector<double> jaw, lens, head;
    std::vector<std::uint8_t> buttons;
    std::vector<std::string> instr;
    if (!scope && rd.Has("jaw")) jaw = rd.Doubles("jaw", 0, &n);
    if (!scope && rd.Has("buttons")) buttons = rd.Bytes("buttons", &n);
    if (!scope && rd.Has("instrument")) instr = rd.Strings("instrument", &n);
    if (scope && rd.Has("lens_roll")) lens = rd.Doubles("lens_roll", 0, &n);
    if (scope && rd.Has("head_roll")) head = rd.Doubles("head_roll", 0, &n);
    for (hsize_t i = 0; i < n; ++i) {
      SessionRow r;
      r.line = static_cast<int>(i) + 1;
      r.device = dev;
      r.t_s = t[i] - options.time_offset_s;
      r.position_mm = Vec3(p[3 * i], p[3 * i + 1], p[3 * i + 2]);
      r.orientation = Quat(q[4 * i], q[4 * i + 1], q[4 * i + 2], q[4 * i + 3]);
      if (!jaw.empty()) {
        r.jaw = jaw[i];
        if (r.jaw < 0.0 || r.jaw > 1.0) rd.Fail("jaw", r.line, "jaw outside [0, 1]");
      }
      if (!buttons.empty()) r.buttons = buttons[i];
      if (!instr.empty()) r.instrument = instr[i] == "none" ? "" : instr[i];
      if (!lens.empty()) r.lens_roll_rad = lens[i];
      if (!head.empty()) r.head_roll_rad = head[i];
      per_device[d].push_back(std::move(r));
    }
  }
  if (!any) throw InputError(path, 0, "", "no /slot0, /slot1 or /scope group: not a session file");
  // File order: a merge by time (device order on ties) that keeps each device's rows as written.
  std::vector<std::size_t> next(kDeviceCount, 0);
  for (;;) {
    int best = -1;
    for (int d = 0; d < kDeviceCount; ++d) {
      if (next[d] >= per_device[d].size()) continue;
      if (best < 0 || per_device[d][next[d]].t_s < per_device[best][next[best]].t_s) best = d;
    }
    if (best < 0) break;
    table.rows.push_back(std::move(per_device[best][next[best]++]));
  }
  if (table.rows.empty()) throw InputError(path, 0, "", "no samples");
  ValidateSession(&table, options);
  return table;
}

}  // namespace

SessionTable ReadSessionHdf5(const std::string& path, const SessionOptions& options) {
  QuietHdf5 quiet;
  return ReadOpenSession(H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), path, options);
}

SessionTable ParseSessionHdf5(const void* image, std::size_t size, const std::string& file,
                              const SessionOptions& options) {
  QuietHdf5 quiet;
  // The core driver without a backing store, opened on a copy of the image: no disk access.
  Handle fapl(H5Pcreate(H5P_FILE_ACCESS), H5Pclose);
  if (fapl.get() < 0 || H5Pset_fapl_core(fapl.get(), 64 * 1024, false) < 0 ||
      H5Pset_file_image(fapl.get(), const_cast<void*>(image), size) < 0) {
    throw InputError(file, 0, "", "cannot open as an HDF5 file");
  }
  return ReadOpenSession(H5Fopen(file.c_str(), H5F_ACC_RDONLY, fapl.get()), file, options);
}

void WriteSessionHdf5(const std::string& path, const SessionTable& table) {
  QuietHdf5 quiet;
  Handle file(H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT), H5Fclose);
  if (file.get() < 0) throw InputError(path, 0, "", "cannot create HDF5 file");
  for (int d = 0; d < kDeviceCount; ++d) {
    const Device dev = static_cast<Device>(d);
    std::vector<double> t, p, q, jaw, lens, head;
    std::vector<std::uint8_t> buttons;
    std::vector<std::string> instr;
    std::size_t max_len = 1;
    for (const SessionRow& r : table.rows) {
      if (r.device != dev) continue;
      t.push_back(r.t_s);
      p.insert(p.end(), {r.position_mm.x(), r.position_mm.y(), r.position_mm.z()});
      q.insert(q.end(),
               {r.orientation.w(), r.orientation.x(), r.orientation.y(), r.orientation.z()});
      jaw.push_back(r.jaw);
      buttons.push_back(r.buttons);
      instr.push_back(r.instrument.empty() ? "none" : r.instrument);
      max_len = std::max(max_len, instr.back().size());
      lens.push_back(r.lens_roll_rad);
      head.push_back(r.head_roll_rad);
    }
    if (t.empty()) continue;
    Handle group(H5Gcreate2(file.get(), DeviceName(dev), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT),
                 H5Gclose);
    if (group.get() < 0) throw InputError(path, 0, DeviceName(dev), "cannot create group");
    const hsize_t n = t.size();
    WriteDataset(path, group.get(), "t", H5T_NATIVE_DOUBLE, H5T_IEEE_F64LE, t, n, 0);
    WriteDataset(path, group.get(), "position", H5T_NATIVE_DOUBLE, H5T_IEEE_F64LE, p, n, 3);
    WriteDataset(path, group.get(), "orientation", H5T_NATIVE_DOUBLE, H5T_IEEE_F64LE, q, n, 4);
    if (dev == Device::kScope) {
      WriteDataset(path, group.get(), "lens_roll", H5T_NATIVE_DOUBLE, H5T_IEEE_F64LE, lens, n, 0);
      WriteDataset(path, group.get(), "head_roll", H5T_NATIVE_DOUBLE, H5T_IEEE_F64LE, head, n, 0);
    } else {
      WriteDataset(path, group.get(), "jaw", H5T_NATIVE_DOUBLE, H5T_IEEE_F64LE, jaw, n, 0);
      WriteDataset(path, group.get(), "buttons", H5T_NATIVE_UINT8, H5T_STD_U8LE, buttons, n, 0);
      std::vector<char> buf(n * max_len, '\0');
      for (hsize_t i = 0; i < n; ++i)
        std::memcpy(buf.data() + i * max_len, instr[i].data(), instr[i].size());
      Handle stype(H5Tcopy(H5T_C_S1), H5Tclose);
      H5Tset_size(stype.get(), max_len);
      H5Tset_strpad(stype.get(), H5T_STR_NULLPAD);
      WriteDataset(path, group.get(), "instrument", stype.get(), stype.get(), buf, n, 0);
    }
  }
}

}  // namespace arthrosim::input
