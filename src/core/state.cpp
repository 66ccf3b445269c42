#include "arthrosim/core/state.h"

#include <algorithm>

#include "arthrosim/core/hash.h"
#include "arthrosim/core/model.h"

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

// One visitor walks every field in a fixed order; equality and hashing share it so that a new
// field cannot be forgotten by one and not the other.
template <class V>
void VisitState(const State& s, V&& v) {
  v(s.step);
  v(s.time_s);
  for (const SoftBodyState& b : s.soft_bodies) {
    v(b.x);
    v(b.v);
    v(b.x_rest);
    v(b.tets);
    v(b.tet_alive);
    v(b.dv_warm);
    v(b.x_factor);
    v(b.removed_volume_mm3);
    v(b.cauterized);
  }
  for (const BoneState& b : s.bones) {
    v(b.surface.nodes);
    v(b.surface.tris);
    v(b.removed_volume_mm3);
    v(b.removed_by_region_mm3);
  }
  for (const ThreadState& t : s.threads) {
    v(t.x);
    v(t.v);
    v(t.node_alive);
  }
  for (const ToolState& t : s.tools) {
    v(t.instrument);
    v(t.pose.position_mm);
    v(t.pose.orientation.coeffs());
    v(t.jaw);
    v(t.buttons);
    v(t.force_n);
  }
  v(s.camera.pose.position_mm);
  v(s.camera.pose.orientation.coeffs());
  v(s.camera.lens_roll_rad);
  v(s.camera.head_roll_rad);
  for (const SpringConstraint& c : s.constraints) {
    v(c.id);
    v(c.tag);
    v(c.stiffness_n_per_mm);
    v(c.rest_length_mm);
    for (const ConstraintEnd* e : {&c.a, &c.b}) {
      v(static_cast<std::uint8_t>(e->kind));
      v(e->index);
      v(e->nodes);
      v(e->weights);
      v(e->offset_mm);
    }
  }
  v(s.next_constraint_id);
  v(s.rng_state);
  for (const Event& e : s.events) {
    v(e.step);
    v(e.time_s);
    v(e.kind);
    v(e.tool);
    v(e.body);
    v(e.detail);
    v(e.position_mm);
  }
  v(s.tool_contacts.size());
  for (const ToolContact& c : s.tool_contacts) {
    v(c.tool_slot);
    v(static_cast<std::uint8_t>(c.body_kind));
    v(c.body);
    v(c.position_mm);
  }
  v(s.holes.size());
  for (const BoneHole& h : s.holes) {
    v(h.bone);
    v(h.tool_slot);
    v(h.entry_mm);
    v(h.axis);
    v(h.depth_mm);
    v(h.diameter_mm);
    v(h.angle_deg);
    v(h.open);
  }
  v(s.anchors.size());
  for (const AnchorState& a : s.anchors) {
    v(a.bone);
    v(a.hole);
    v(a.position_mm);
    v(a.axis);
    v(a.depth_mm);
    v(a.angle_deg);
  }
}

// Feeds each field's shape and raw bytes to put(pointer, bytes).
template <class Put>
struct ByteVisitor {
  Put put;
  template <class T>
  void operator()(const T& value) {
    if constexpr (std::is_arithmetic_v<T>) {
      put(&value, sizeof(T));
    } else if constexpr (std::is_same_v<T, std::string>) {
      const std::size_t n = value.size();
      put(&n, sizeof n);
      put(value.data(), n);
    } else if constexpr (requires { value.rows(); }) {  // Eigen dense
      const std::int64_t shape[2] = {value.rows(), value.cols()};
      put(shape, sizeof shape);
      put(value.data(), sizeof(double) * static_cast<std::size_t>(value.size()));
    } else {  // std::vector / std::array of trivially copyable elements
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
  VisitState(s, ByteVisitor<decltype(put)>{put});
  return out;
}

}  // namespace

std::uint64_t HashState(const State& s) {
  Fnv1a h;
  auto put = [&h](const void* p, std::size_t n) { h.Add(p, n); };
  VisitState(s, ByteVisitor<decltype(put)>{put});
  return h.digest();
}

bool BitwiseEqual(const State& a, const State& b) { return Serialize(a) == Serialize(b); }

}  // namespace arthrosim
