#pragma once
// Private to the run writer and reader: how a State field of the field table
// (core/state_fields.h) stored per frame maps to an HDF5 dataset (element types, row shape, fill
// value), so that both sides derive every per-frame dataset from the same table.
#include <array>
#include <cstdint>
#include <limits>
#include <type_traits>
#include <vector>

#include "arthrosim/core/state_fields.h"
#include "arthrosim/io/hdf5.h"

namespace arthrosim::io::detail {

/// HDF5 types and row shape of one per-frame value of C++ type T.
struct ValueType {
  hid_t file = -1;          ///< little-endian file type
  hid_t mem = -1;           ///< native memory type
  hsize_t width = 0;        ///< trailing dimension (3 vector, 7 pose), 0 for none
  bool per_node = false;    ///< one row per node / element: [N] or [N, width], N extensible
  bool row_vector = false;  ///< a std::vector of fixed length: [L], L from the first frame
};

/// Whether T can be stored per frame ([T, ...] dataset).
template <class T>
inline constexpr bool kFrameValue =
    std::is_same_v<T, double> || std::is_same_v<T, std::int64_t> ||
    std::is_same_v<T, std::uint64_t> || std::is_same_v<T, std::int32_t> ||
    std::is_same_v<T, std::uint8_t> || std::is_same_v<T, Vec3> || std::is_same_v<T, Pose> ||
    std::is_same_v<T, Points> || std::is_same_v<T, std::vector<std::uint8_t>> ||
    std::is_same_v<T, std::vector<double>>;

template <class T>
ValueType TypeOf() {
  static_assert(kFrameValue<T>);
  if constexpr (std::is_same_v<T, double>) return {H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, 0, false};
  if constexpr (std::is_same_v<T, std::int64_t>) return {H5T_STD_I64LE, H5T_NATIVE_INT64, 0, false};
  if constexpr (std::is_same_v<T, std::uint64_t>)
    return {H5T_STD_U64LE, H5T_NATIVE_UINT64, 0, false};
  if constexpr (std::is_same_v<T, std::int32_t>) return {H5T_STD_I32LE, H5T_NATIVE_INT32, 0, false};
  if constexpr (std::is_same_v<T, std::uint8_t>) return {H5T_STD_U8LE, H5T_NATIVE_UINT8, 0, false};
  if constexpr (std::is_same_v<T, Vec3>) return {H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, 3, false};
  if constexpr (std::is_same_v<T, Pose>) return {H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, 7, false};
  if constexpr (std::is_same_v<T, Points>) return {H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, 3, true};
  if constexpr (std::is_same_v<T, std::vector<std::uint8_t>>)
    return {H5T_STD_U8LE, H5T_NATIVE_UINT8, 0, true};
  if constexpr (std::is_same_v<T, std::vector<double>>)
    return {H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, 0, false, true};
  return {};
}

/// Element type of T in memory (double for vectors, poses and positions).
template <class T>
using ElementOf = std::conditional_t<
    std::is_same_v<T, Vec3> || std::is_same_v<T, Pose> || std::is_same_v<T, Points>, double,
    std::conditional_t<std::is_same_v<T, std::vector<std::uint8_t>>, std::uint8_t,
                       std::conditional_t<std::is_same_v<T, std::vector<double>>, double, T>>>;

/// The fill value of a field in its element type, or nullptr for HDF5's default (zeros).
template <class T>
const void* FillOf(FieldFill fill) {
  using E = ElementOf<T>;
  static constexpr E kZero{};
  if (fill == FieldFill::kZero) return &kZero;
  if constexpr (std::is_floating_point_v<E>) {
    static constexpr E kNaN = std::numeric_limits<E>::quiet_NaN();
    if (fill == FieldFill::kNaN) return &kNaN;
  }
  if constexpr (std::is_signed_v<E> && std::is_integral_v<E>) {
    static constexpr E kMinusOne = -1;
    if (fill == FieldFill::kMinusOne) return &kMinusOne;
  }
  return nullptr;
}

/// Rows of a per-node value (nodes or elements), 1 otherwise.
template <class T>
hsize_t RowsOf(const T& v) {
  if constexpr (std::is_same_v<T, Points>) return static_cast<hsize_t>(v.cols());
  if constexpr (std::is_same_v<T, std::vector<std::uint8_t>> ||
                std::is_same_v<T, std::vector<double>>)
    return v.size();
  return 1;
}

/// x y z qw qx qy qz (Eigen stores x y z w).
inline std::array<double, 7> PoseRow(const Pose& p) {
  return {p.position_mm.x(), p.position_mm.y(), p.position_mm.z(), p.orientation.w(),
          p.orientation.x(), p.orientation.y(), p.orientation.z()};
}

inline Pose PoseFromRow(const double* r) {
  Pose p;
  p.position_mm = Vec3(r[0], r[1], r[2]);
  p.orientation = Quat(r[3], r[4], r[5], r[6]);  // Eigen's constructor order: w x y z
  return p;
}

/// The value's elements in memory order; poses are converted into *pose first.
template <class T>
const void* DataOf(const T& v, std::array<double, 7>* pose) {
  if constexpr (std::is_same_v<T, Pose>) {
    *pose = PoseRow(v);
    return pose->data();
  } else if constexpr (std::is_arithmetic_v<T>) {
    return &v;
  } else {
    return v.data();
  }
}

/// Bytes of one row-set of the value (all its rows).
template <class T>
std::size_t BytesOf(const T& v) {
  const ValueType t = TypeOf<T>();
  return sizeof(ElementOf<T>) * RowsOf(v) * (t.width > 0 ? t.width : 1);
}

}  // namespace arthrosim::io::detail
