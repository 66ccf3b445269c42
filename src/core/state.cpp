#include "arthrosim/core/state.h"

#include <algorithm>

#include "arthrosim/core/hash.h"
#include "arthrosim/core/model.h"
#include "arthrosim/core/state_fields.h"

namespace arthrosim {

State MakeInitialState(const Model& model) {
  State s;
  s.rng_state = model.options.seed;
  for (const SoftBodyModel& body : model.soft_bodies) {
    SoftBodyState b;
    b.x = body.rest_mesh.nodes;
    b.x_rest = body.rest_mesh.nodes;
    b.v = Points::Zero(3, body.rest_mesh.nodes.cols());
    b.dv_warm = Points::Zero(3, body.rest_mesh.nodes.cols());
    b.tets = body.rest_mesh.tets;
    b.tet_alive.assign(b.tets.size(), 1);
    s.soft_bodies.push_back(std::move(b));
  }
  for (const BoneModel& bone : model.bones) {
    s.bones.push_back(BoneState{bone.surface, 0.0, {}});
    s.bones.back().removed_by_region_mm3.assign(model.regions.size() + 1, 0.0);
  }
  for (const ThreadModel& thread : model.threads) {
    ThreadState t;
    t.x = thread.initial.nodes;
    t.v = Points::Zero(3, thread.initial.nodes.cols());
    // A suture the anchor carries is not in the scene until the anchor is seated.
    const auto& carried = model.operations.anchor.sutures;
    const bool on_anchor = std::find(carried.begin(), carried.end(), thread.name) != carried.end();
    t.node_alive.assign(thread.initial.nodes.cols(), on_anchor ? 0 : 1);
    s.threads.push_back(std::move(t));
  }
  s.camera.pose = model.camera.initial_pose;
  return s;
}

namespace {

template <class T>
concept HasFields = requires(const T& t) {
  VisitFields(t, [](const auto&, const FieldInfo&) {});
};

// Feeds each field's shape and raw bytes to put(pointer, bytes), walking the State field table
// (core/state_fields.h) so that a field cannot be hashed and not compared, or the reverse.
template <class Put>
struct ByteVisitor {
  Put put;
  template <class T>
  void operator()(const T& value, const FieldInfo& info) {
    if (info.store != FieldStore::kDerived) Bytes(value);  // derived data is not identity
  }
  template <class T>
  void Bytes(const T& value) {
    if constexpr (std::is_arithmetic_v<T> || std::is_enum_v<T>) {
      put(&value, sizeof(T));
    } else if constexpr (std::is_same_v<T, std::string>) {
      const std::size_t n = value.size();
      put(&n, sizeof n);
      put(value.data(), n);
    } else if constexpr (std::is_same_v<T, Pose>) {
      Bytes(value.position_mm);
      Bytes(value.orientation.coeffs());
    } else if constexpr (requires { value.rows(); }) {  // Eigen dense
      const std::int64_t shape[2] = {value.rows(), value.cols()};
      put(shape, sizeof shape);
      put(value.data(), sizeof(double) * static_cast<std::size_t>(value.size()));
    } else if constexpr (HasFields<T>) {
      VisitFields(value, *this);
    } else if constexpr (HasFields<typename T::value_type>) {  // list of structs
      const std::size_t n = value.size();
      put(&n, sizeof n);
      for (const auto& item : value) Bytes(item);
    } else {  // std::vector / std::array of trivially copyable elements
      static_assert(std::is_trivially_copyable_v<typename T::value_type>);
      const std::size_t n = value.size();
      put(&n, sizeof n);
      put(value.data(), sizeof(value[0]) * n);
    }
  }
};

std::vector<std::uint8_t> Serialize(const State& s) {
  std::vector<std::uint8_t> out;
  auto put = [&out](const void* p, std::size_t n) {
    const auto* c = static_cast<const std::uint8_t*>(p);
    out.insert(out.end(), c, c + n);
  };
  ByteVisitor<decltype(put)>{put}.Bytes(s);
  return out;
}

}  // namespace

std::uint64_t HashState(const State& s) {
  Fnv1a h;
  auto put = [&h](const void* p, std::size_t n) { h.Add(p, n); };
  ByteVisitor<decltype(put)>{put}.Bytes(s);
  return h.digest();
}

bool BitwiseEqual(const State& a, const State& b) { return Serialize(a) == Serialize(b); }

}  // namespace arthrosim
