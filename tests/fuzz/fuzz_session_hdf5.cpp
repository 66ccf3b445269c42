// Fuzz target: the HDF5 session reader (input::ParseSessionHdf5). The fuzz bytes do not become
// the file: they choose the groups, dataset names, types, shapes and values of a well-formed
// HDF5 file built in memory (core driver, no disk), which the reader then parses. Random bytes
// as an HDF5 file would fuzz libhdf5's own format parser, which is not ours to fix
// (docs/fuzzing.md); this fuzzes everything our reader does with what a valid file holds.
#include <fuzzer/FuzzedDataProvider.h>
#include <hdf5.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

#include "arthrosim/core/hdf5_handle.h"
#include "arthrosim/input/session.h"
#include "fuzz_util.h"

namespace {

using arthrosim::h5::Handle;

constexpr const char* kGroups[] = {"slot0", "slot1", "scope", "other"};
constexpr const char* kDatasets[] = {"t",       "position",   "orientation", "jaw",
                                     "buttons", "instrument", "lens_roll",   "head_roll"};
enum class Kind { kDouble, kFloat, kInt64, kInt16, kUint8, kFixedString, kVarString, kCompound };
constexpr Kind kKinds[] = {Kind::kDouble, Kind::kFloat,       Kind::kInt64,     Kind::kInt16,
                           Kind::kUint8,  Kind::kFixedString, Kind::kVarString, Kind::kCompound};

// A number from one byte: mostly plausible session values (times, unit quaternion parts, jaw),
// sometimes the awkward ones (NaN, infinities, huge, negative zero).
double Number(FuzzedDataProvider& fdp) {
  const auto b = fdp.ConsumeIntegral<std::uint8_t>();
  if (b < 128) return b * 0.01;
  if (b < 192) return -(b - 128) * 0.5;
  constexpr double kSpecial[] = {std::numeric_limits<double>::quiet_NaN(),
                                 std::numeric_limits<double>::infinity(),
                                 -std::numeric_limits<double>::infinity(),
                                 1e308,
                                 -0.0,
                                 1.0,
                                 0.7071067811865476,
                                 1e-3,
                                 4e9,
                                 -1e-300};
  return kSpecial[(b - 192) % (sizeof(kSpecial) / sizeof(kSpecial[0]))];
}

// The file type of a dataset of kind k; fixed strings get a length from the bytes.
Handle FileType(Kind k, FuzzedDataProvider& fdp) {
  switch (k) {
    case Kind::kDouble:
      return Handle(H5Tcopy(H5T_IEEE_F64LE), H5Tclose);
    case Kind::kFloat:
      return Handle(H5Tcopy(H5T_IEEE_F32BE), H5Tclose);
    case Kind::kInt64:
      return Handle(H5Tcopy(H5T_STD_I64LE), H5Tclose);
    case Kind::kInt16:
      return Handle(H5Tcopy(H5T_STD_I16BE), H5Tclose);
    case Kind::kUint8:
      return Handle(H5Tcopy(H5T_STD_U8LE), H5Tclose);
    case Kind::kFixedString: {
      Handle t(H5Tcopy(H5T_C_S1), H5Tclose);
      H5Tset_size(t.get(), fdp.ConsumeIntegralInRange<std::size_t>(1, 12));
      H5Tset_strpad(t.get(), fdp.ConsumeBool() ? H5T_STR_NULLPAD : H5T_STR_NULLTERM);
      return t;
    }
    case Kind::kVarString: {
      Handle t(H5Tcopy(H5T_C_S1), H5Tclose);
      H5Tset_size(t.get(), H5T_VARIABLE);
      return t;
    }
    case Kind::kCompound: {
      Handle t(H5Tcreate(H5T_COMPOUND, 16), H5Tclose);
      H5Tinsert(t.get(), "a", 0, H5T_NATIVE_DOUBLE);
      H5Tinsert(t.get(), "b", 8, H5T_NATIVE_DOUBLE);
      return t;
    }
  }
  return Handle();
}

// Writes `count` values of kind k into dataset d (file type ftype) from the bytes.
void WriteValues(hid_t d, hid_t ftype, Kind k, std::size_t count, FuzzedDataProvider& fdp) {
  switch (k) {
    case Kind::kDouble:
    case Kind::kFloat:
    case Kind::kCompound: {
      std::vector<double> v(count * (k == Kind::kCompound ? 2 : 1));
      for (double& x : v) x = Number(fdp);
      H5Dwrite(d, k == Kind::kCompound ? ftype : H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT,
               v.data());
      return;
    }
    case Kind::kInt64:
    case Kind::kInt16:
    case Kind::kUint8: {
      std::vector<std::int64_t> v(count);
      for (std::int64_t& x : v) x = static_cast<std::int8_t>(fdp.ConsumeIntegral<std::uint8_t>());
      H5Dwrite(d, H5T_NATIVE_INT64, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data());
      return;
    }
    case Kind::kFixedString: {
      const std::size_t len = H5Tget_size(ftype);
      std::vector<char> buf(count * len, '\0');
      for (std::size_t i = 0; i < count; ++i) {
        const std::string s = fdp.ConsumeRandomLengthString(len);
        std::memcpy(buf.data() + i * len, s.data(), std::min(len, s.size()));
      }
      H5Dwrite(d, ftype, H5S_ALL, H5S_ALL, H5P_DEFAULT, buf.data());
      return;
    }
    case Kind::kVarString: {
      std::vector<std::string> s(count);
      std::vector<const char*> p(count);
      for (std::size_t i = 0; i < count; ++i) {
        s[i] = fdp.ConsumeRandomLengthString(16);
        p[i] = s[i].c_str();
      }
      H5Dwrite(d, ftype, H5S_ALL, H5S_ALL, H5P_DEFAULT, p.data());
      return;
    }
  }
}

// One dataset `name` in `parent`: kind, rank 0-3 and shape from the bytes. Mostly small and
// written; sometimes huge, chunked and never written (reads give the fill value), as a file a
// few hundred bytes long can declare.
void AddDataset(hid_t parent, const char* name, FuzzedDataProvider& fdp) {
  const Kind k = fdp.PickValueInArray(kKinds);
  Handle ftype = FileType(k, fdp);
  const int rank = fdp.ConsumeIntegralInRange(0, 3);
  const bool huge = fdp.ConsumeIntegralInRange(0, 15) == 0;
  hsize_t dims[3] = {0, 0, 0}, maxdims[3], chunk[3];
  std::size_t count = 1;
  for (int i = 0; i < rank; ++i) {
    dims[i] = huge ? fdp.ConsumeIntegralInRange<hsize_t>(0, hsize_t{1} << 40)
                   : fdp.ConsumeIntegralInRange<hsize_t>(0, 6);
    maxdims[i] = H5S_UNLIMITED;
    chunk[i] = 4;
    count *= huge ? 0 : static_cast<std::size_t>(dims[i]);
  }
  Handle space(rank == 0 ? H5Screate(H5S_SCALAR) : H5Screate_simple(rank, dims, maxdims), H5Sclose);
  Handle dcpl(H5Pcreate(H5P_DATASET_CREATE), H5Pclose);
  if (rank > 0) H5Pset_chunk(dcpl.get(), rank, chunk);
  Handle d(H5Dcreate2(parent, name, ftype.get(), space.get(), H5P_DEFAULT, dcpl.get(), H5P_DEFAULT),
           H5Dclose);
  if (d.get() < 0 || huge || count == 0) return;
  WriteValues(d.get(), ftype.get(), k, count, fdp);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const bool quiet = [] { return H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr) >= 0; }();
  (void)quiet;
  FuzzedDataProvider fdp(data, size);
  std::vector<unsigned char> image;
  {
    Handle fapl(H5Pcreate(H5P_FILE_ACCESS), H5Pclose);
    H5Pset_fapl_core(fapl.get(), 64 * 1024, false);
    Handle file(H5Fcreate("fuzz.h5", H5F_ACC_TRUNC, H5P_DEFAULT, fapl.get()), H5Fclose);
    if (file.get() < 0) return 0;
    const int groups = fdp.ConsumeIntegralInRange(0, 4);
    for (int g = 0; g < groups; ++g) {
      const char* name = fdp.PickValueInArray(kGroups);
      if (H5Lexists(file.get(), name, H5P_DEFAULT) > 0) continue;
      if (fdp.ConsumeIntegralInRange(0, 7) == 0) {  // a dataset where a group belongs
        AddDataset(file.get(), name, fdp);
        continue;
      }
      Handle group(H5Gcreate2(file.get(), name, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), H5Gclose);
      const int datasets = fdp.ConsumeIntegralInRange(0, 8);
      for (int i = 0; i < datasets; ++i) {
        const char* ds = fdp.PickValueInArray(kDatasets);
        if (H5Lexists(group.get(), ds, H5P_DEFAULT) <= 0) AddDataset(group.get(), ds, fdp);
      }
    }
    H5Fflush(file.get(), H5F_SCOPE_GLOBAL);
    const ssize_t n = H5Fget_file_image(file.get(), nullptr, 0);
    if (n <= 0) return 0;
    image.resize(static_cast<std::size_t>(n));
    if (H5Fget_file_image(file.get(), image.data(), image.size()) != n) return 0;
  }
  arthrosim::fuzz::ExpectOnlyInputErrors(
      [&] { arthrosim::input::ParseSessionHdf5(image.data(), image.size(), "fuzz.h5"); });
  return 0;
}
