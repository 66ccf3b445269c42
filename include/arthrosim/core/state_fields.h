#pragma once
// The State field table: one visitor per State struct names every member once, with how the run
// file keeps it (dataset name, unit, storage). HashState, BitwiseEqual, the run writer and the
// run reader all walk these visitors, so a new State field is hashed, compared, written, read
// and documented (docs/hdf5-layout.md, checked by a test) by adding one line here.
// tests/core/state_fields_test.cpp fails when a struct has a member its visitor does not name.
//
// A visitor is called as v(member, info) for every member, in declaration order; `S` is the
// struct, const or not (the reader fills a State through the same visitors).
#include <array>
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <type_traits>

#include "arthrosim/core/state.h"

namespace arthrosim {

/// How the run file keeps a State field.
enum class FieldStore : std::uint8_t {
  kFrame,    ///< one row per frame, [T, ...]; rows follow the entity's node/element count
  kBlocks,   ///< block series: rows written only when they changed (+ _offset, _count)
  kAppend,   ///< append-only rows: every row ever (tets: splits only append)
  kRecords,  ///< a list of records stored as a block series of compound rows
  kEvents,   ///< the event stream (/events + /events_end)
  kGroup,    ///< a nested entity: its own fields, in its group (bodies, slots, camera...)
  kNested,   ///< a nested value whose fields are stored in this entity's group
  kDerived,  ///< not stored: the reader recomputes it (documented with the dataset list)
  kNone,     ///< not in the frames: velocities, rest positions, solver warm starts and input
             ///< controllers are kept only in the run file's checkpoints (/checkpoints)
};

/// What a growing per-frame array's length follows.
enum class FieldDim : std::uint8_t {
  kFixed,     ///< a fixed row shape (scalars, vectors, poses, per-slot values)
  kNodes,     ///< one row per node: [T, N, ...], N extensible
  kElements,  ///< one row per element: [T, E, ...], E extensible
};

/// Value of rows that do not exist (yet) in a frame, and of fresh chunks.
enum class FieldFill : std::uint8_t { kDefault, kZero, kNaN, kMinusOne };

/// How the run file keeps one State member.
struct FieldInfo {
  const char* name;  ///< dataset (or group / record member) name
  const char* unit;  ///< "" when dimensionless
  FieldStore store;
  FieldDim dim = FieldDim::kFixed;
  FieldFill fill = FieldFill::kDefault;
  bool bulk_float = false;  ///< bulk coordinates: compressed by float_deflate_level
  /// Per-node marks kept empty (or short) in State while unmarked: stored padded with zeros to
  /// the node count, read back empty when every entry is 0.
  bool sparse = false;
};

template <class S, class T>
concept FieldsOf = std::is_same_v<std::remove_const_t<S>, T>;

/// Every member of a soft body.
template <class S, class V>
requires FieldsOf<S, SoftBodyState>
void VisitFields(S& b, V&& v) {
  v(b.x,
    FieldInfo{"positions", "mm", FieldStore::kBlocks, FieldDim::kNodes, FieldFill::kNaN, true});
  v(b.v, FieldInfo{"velocities", "mm/s", FieldStore::kNone});
  v(b.x_rest, FieldInfo{"rest_positions", "mm", FieldStore::kNone});
  v(b.tets, FieldInfo{"elements", "", FieldStore::kAppend});
  v(b.tet_alive,
    FieldInfo{"element_alive", "", FieldStore::kFrame, FieldDim::kElements, FieldFill::kZero});
  v(b.dv_warm, FieldInfo{"dv_warm", "mm/s", FieldStore::kNone});
  v(b.x_factor, FieldInfo{"x_factor", "mm", FieldStore::kNone});
  v(b.factor_rest, FieldInfo{"factor_rest", "mm", FieldStore::kNone});
  v(b.factor_alive, FieldInfo{"factor_alive", "", FieldStore::kNone});
  v(b.x_factor_next, FieldInfo{"x_factor_next", "mm", FieldStore::kNone});
  v(b.factor_rest_next, FieldInfo{"factor_rest_next", "mm", FieldStore::kNone});
  v(b.factor_alive_next, FieldInfo{"factor_alive_next", "", FieldStore::kNone});
  v(b.removed_volume_mm3, FieldInfo{"removed_volume", "mm3", FieldStore::kFrame});
  v(b.cauterized, FieldInfo{"cauterized", "", FieldStore::kFrame, FieldDim::kNodes,
                            FieldFill::kZero, false, true});
}

/// A triangle surface.
template <class S, class V>
requires FieldsOf<S, mesh::TriMesh>
void VisitFields(S& m, V&& v) {
  v(m.nodes,
    FieldInfo{"vertices", "mm", FieldStore::kBlocks, FieldDim::kFixed, FieldFill::kDefault, true});
  v(m.tris, FieldInfo{"triangles", "", FieldStore::kBlocks});
}

/// Every member of a bone.
template <class S, class V>
requires FieldsOf<S, BoneState>
void VisitFields(S& b, V&& v) {
  v(b.surface, FieldInfo{"surface", "", FieldStore::kNested});
  v(b.removed_volume_mm3, FieldInfo{"removed_volume", "mm3", FieldStore::kFrame});
  // One column per Model region plus "elsewhere": a fixed-width row per frame.
  v(b.removed_by_region_mm3, FieldInfo{"removed_volume_by_region", "mm3", FieldStore::kFrame});
  // Derived by the reader: a number that changes whenever the stored surface block changes.
  v(b.revision, FieldInfo{"revision", "", FieldStore::kDerived});
}

/// Every member of a suture thread.
template <class S, class V>
requires FieldsOf<S, ThreadState>
void VisitFields(S& t, V&& v) {
  v(t.x,
    FieldInfo{"positions", "mm", FieldStore::kBlocks, FieldDim::kNodes, FieldFill::kNaN, true});
  v(t.v, FieldInfo{"velocities", "mm/s", FieldStore::kNone});
  v(t.node_alive,
    FieldInfo{"node_alive", "", FieldStore::kFrame, FieldDim::kNodes, FieldFill::kZero});
}

/// Every member of one constraint end.
template <class S, class V>
requires FieldsOf<S, ConstraintEnd>
void VisitFields(S& e, V&& v) {
  v(e.kind, FieldInfo{"kind", "", FieldStore::kFrame});
  v(e.index, FieldInfo{"index", "", FieldStore::kFrame});
  v(e.nodes, FieldInfo{"nodes", "", FieldStore::kFrame});
  v(e.weights, FieldInfo{"weights", "", FieldStore::kFrame});
  v(e.offset_mm, FieldInfo{"offset_mm", "mm", FieldStore::kFrame});
}

/// Every member of a spring constraint (a record of /constraints/rows).
template <class S, class V>
requires FieldsOf<S, SpringConstraint>
void VisitFields(S& c, V&& v) {
  v(c.id, FieldInfo{"id", "", FieldStore::kFrame});
  v(c.tag, FieldInfo{"tag", "", FieldStore::kFrame});
  v(c.a, FieldInfo{"a", "", FieldStore::kNested});
  v(c.b, FieldInfo{"b", "", FieldStore::kNested});
  v(c.stiffness_n_per_mm, FieldInfo{"stiffness", "N/mm", FieldStore::kFrame});
  v(c.rest_length_mm, FieldInfo{"rest_length", "mm", FieldStore::kFrame});
  v(c.slide_friction_n, FieldInfo{"slide_friction", "N", FieldStore::kFrame});
}

/// Every member of a tool slot (/tool_slots: one row of kToolSlots values per frame).
template <class S, class V>
requires FieldsOf<S, ToolState>
void VisitFields(S& t, V&& v) {
  v(t.instrument,
    FieldInfo{"instrument", "", FieldStore::kFrame, FieldDim::kFixed, FieldFill::kMinusOne});
  v(t.pose, FieldInfo{"pose", "mm, quaternion", FieldStore::kFrame});
  v(t.handle_pose, FieldInfo{"handle_pose", "mm, quaternion", FieldStore::kFrame});
  v(t.jaw, FieldInfo{"jaw", "", FieldStore::kFrame});
  v(t.buttons, FieldInfo{"buttons", "", FieldStore::kFrame});
  v(t.force_n, FieldInfo{"force", "N", FieldStore::kFrame});
  v(t.tissue_force_n, FieldInfo{"tissue_force", "N", FieldStore::kFrame});
}

/// Every member of the arthroscope.
template <class S, class V>
requires FieldsOf<S, CameraState>
void VisitFields(S& c, V&& v) {
  v(c.pose, FieldInfo{"pose", "mm, quaternion", FieldStore::kFrame});
  v(c.lens_roll_rad, FieldInfo{"lens_roll", "rad", FieldStore::kFrame});
  v(c.head_roll_rad, FieldInfo{"head_roll", "rad", FieldStore::kFrame});
}

/// Every member of an event (a record of /events).
template <class S, class V>
requires FieldsOf<S, Event>
void VisitFields(S& e, V&& v) {
  v(e.step, FieldInfo{"step", "", FieldStore::kFrame});
  v(e.time_s, FieldInfo{"time", "s", FieldStore::kFrame});
  v(e.kind, FieldInfo{"kind", "", FieldStore::kFrame});
  v(e.tool, FieldInfo{"tool", "", FieldStore::kFrame});
  v(e.body, FieldInfo{"body", "", FieldStore::kFrame});
  v(e.detail, FieldInfo{"detail", "", FieldStore::kFrame});
  v(e.position_mm, FieldInfo{"position", "mm", FieldStore::kFrame});
}

/// Every member of a tool contact (a record of /tool_contacts/rows).
template <class S, class V>
requires FieldsOf<S, ToolContact>
void VisitFields(S& c, V&& v) {
  v(c.tool_slot, FieldInfo{"tool_slot", "", FieldStore::kFrame});
  v(c.body_kind, FieldInfo{"body_kind", "", FieldStore::kFrame});
  v(c.body, FieldInfo{"body", "", FieldStore::kFrame});
  v(c.position_mm, FieldInfo{"position", "mm", FieldStore::kFrame});
}

/// Every member of an awl hole (a float64 row of /holes/rows).
template <class S, class V>
requires FieldsOf<S, BoneHole>
void VisitFields(S& h, V&& v) {
  v(h.bone, FieldInfo{"bone", "", FieldStore::kFrame});
  v(h.tool_slot, FieldInfo{"tool_slot", "", FieldStore::kFrame});
  v(h.entry_mm, FieldInfo{"entry", "mm", FieldStore::kFrame});
  v(h.axis, FieldInfo{"axis", "", FieldStore::kFrame});
  v(h.depth_mm, FieldInfo{"depth", "mm", FieldStore::kFrame});
  v(h.diameter_mm, FieldInfo{"diameter", "mm", FieldStore::kFrame});
  v(h.angle_deg, FieldInfo{"angle", "deg", FieldStore::kFrame});
  v(h.open, FieldInfo{"open", "", FieldStore::kFrame});
}

/// Every member of a seated anchor (a float64 row of /anchors/rows).
template <class S, class V>
requires FieldsOf<S, AnchorState>
void VisitFields(S& a, V&& v) {
  v(a.bone, FieldInfo{"bone", "", FieldStore::kFrame});
  v(a.hole, FieldInfo{"hole", "", FieldStore::kFrame});
  v(a.position_mm, FieldInfo{"position", "mm", FieldStore::kFrame});
  v(a.axis, FieldInfo{"axis", "", FieldStore::kFrame});
  v(a.depth_mm, FieldInfo{"depth", "mm", FieldStore::kFrame});
  v(a.angle_deg, FieldInfo{"angle", "deg", FieldStore::kFrame});
}

/// Every member of a script force-push controller (checkpoints only).
template <class S, class V>
requires FieldsOf<S, ScriptPushState>
void VisitFields(S& p, V&& v) {
  v(p.action, FieldInfo{"action", "", FieldStore::kNone});
  v(p.depth_mm, FieldInfo{"depth", "mm", FieldStore::kNone});
  v(p.t_prev_s, FieldInfo{"t_prev", "s", FieldStore::kNone});
}

/// Every member of the State (root datasets and the entity groups).
template <class S, class V>
requires FieldsOf<S, State>
void VisitFields(S& s, V&& v) {
  v(s.step, FieldInfo{"step", "", FieldStore::kFrame});
  v(s.time_s, FieldInfo{"time", "s", FieldStore::kFrame});
  v(s.soft_bodies, FieldInfo{"bodies", "", FieldStore::kGroup});
  v(s.bones, FieldInfo{"bones", "", FieldStore::kGroup});
  v(s.threads, FieldInfo{"threads", "", FieldStore::kGroup});
  v(s.tools, FieldInfo{"tool_slots", "", FieldStore::kGroup});
  v(s.camera, FieldInfo{"camera", "", FieldStore::kGroup});
  v(s.constraints, FieldInfo{"constraints", "", FieldStore::kRecords});
  v(s.next_constraint_id, FieldInfo{"next_constraint_id", "", FieldStore::kFrame});
  v(s.rng_state, FieldInfo{"rng_state", "", FieldStore::kFrame});
  v(s.events, FieldInfo{"events", "", FieldStore::kEvents});
  v(s.tool_contacts, FieldInfo{"tool_contacts", "", FieldStore::kRecords});
  v(s.holes, FieldInfo{"holes", "", FieldStore::kRecords});
  v(s.anchors, FieldInfo{"anchors", "", FieldStore::kRecords});
  v(s.script_push, FieldInfo{"script_push", "", FieldStore::kNone});
  v(s.factor_switch_step, FieldInfo{"factor_switch_step", "", FieldStore::kNone});
  v(s.factor_baseline_cg, FieldInfo{"factor_baseline_cg", "", FieldStore::kNone});
}

/// The most members any State struct has (State itself: 17).
constexpr std::size_t kMaxStateFields = 32;

/// Addresses of the members of `object` in table order, into `out`; returns how many (0 when
/// object is null). Pairs a struct's members with another object's of the same type.
template <class T>
std::size_t FieldAddresses(const T* object, std::array<const void*, kMaxStateFields>* out) {
  std::size_t n = 0;
  if (object == nullptr) return 0;
  VisitFields(*object, [&](const auto& member, const FieldInfo&) {
    if (n >= kMaxStateFields) throw std::logic_error("FieldAddresses: raise kMaxStateFields");
    (*out)[n++] = &member;
  });
  return n;
}

/// The table's entry for `member` of `object` (e.g. FieldOf(tri_mesh, tri_mesh.tris).name is
/// "triangles"); throws std::logic_error if member is not a member of object.
template <class S, class M>
FieldInfo FieldOf(const S& object, const M& member) {
  const FieldInfo* found = nullptr;
  FieldInfo info_found{"", "", FieldStore::kNone};
  VisitFields(object, [&](const auto& value, const FieldInfo& info) {
    if (static_cast<const void*>(&value) == static_cast<const void*>(&member)) {
      info_found = info;
      found = &info_found;
    }
  });
  if (found == nullptr) throw std::logic_error("FieldOf: not a member of the object");
  return info_found;
}

}  // namespace arthrosim
