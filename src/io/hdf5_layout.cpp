#include "arthrosim/io/hdf5_layout.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstring>

#include "arthrosim/core/state_fields.h"

namespace arthrosim::io::layout {
namespace {

h5::Handle StringType(int width) {
  h5::Handle t(H5Tcopy(H5T_C_S1), H5Tclose);
  H5Tset_size(t.get(), static_cast<std::size_t>(width));
  H5Tset_strpad(t.get(), H5T_STR_NULLPAD);
  return t;
}

h5::Handle ArrayType(hid_t base, hsize_t n) {
  return h5::Handle(H5Tarray_create2(base, 1, &n), H5Tclose);
}

void Pack(h5::Handle& t, bool packed) {
  if (packed) H5Tpack(t.get());
}

h5::Handle EndType(bool packed) {
  const ConstraintEnd end;  // field names from the State field table
  h5::Handle t(H5Tcreate(H5T_COMPOUND, sizeof(ConstraintEndRecord)), H5Tclose);
  h5::Handle i4 = ArrayType(H5T_NATIVE_INT32, 4);
  h5::Handle f4 = ArrayType(H5T_NATIVE_DOUBLE, 4);
  h5::Handle f3 = ArrayType(H5T_NATIVE_DOUBLE, 3);
  H5Tinsert(t.get(), FieldOf(end, end.kind).name, offsetof(ConstraintEndRecord, kind),
            H5T_NATIVE_UINT8);
  H5Tinsert(t.get(), FieldOf(end, end.index).name, offsetof(ConstraintEndRecord, index),
            H5T_NATIVE_INT32);
  H5Tinsert(t.get(), FieldOf(end, end.nodes).name, offsetof(ConstraintEndRecord, nodes), i4.get());
  H5Tinsert(t.get(), FieldOf(end, end.weights).name, offsetof(ConstraintEndRecord, weights),
            f4.get());
  H5Tinsert(t.get(), FieldOf(end, end.offset_mm).name, offsetof(ConstraintEndRecord, offset_mm),
            f3.get());
  Pack(t, packed);
  return t;
}

}  // namespace

h5::Handle EventType(bool packed) {
  const Event event;  // field names from the State field table
  h5::Handle t(H5Tcreate(H5T_COMPOUND, sizeof(EventRecord)), H5Tclose);
  h5::Handle kind = StringType(kKindChars);
  h5::Handle name = StringType(kNameChars);
  h5::Handle detail = StringType(kDetailChars);
  h5::Handle f3 = ArrayType(H5T_NATIVE_DOUBLE, 3);
  H5Tinsert(t.get(), FieldOf(event, event.step).name, offsetof(EventRecord, step),
            H5T_NATIVE_INT64);
  H5Tinsert(t.get(), FieldOf(event, event.time_s).name, offsetof(EventRecord, time_s),
            H5T_NATIVE_DOUBLE);
  H5Tinsert(t.get(), FieldOf(event, event.kind).name, offsetof(EventRecord, kind), kind.get());
  H5Tinsert(t.get(), FieldOf(event, event.tool).name, offsetof(EventRecord, tool), name.get());
  H5Tinsert(t.get(), FieldOf(event, event.body).name, offsetof(EventRecord, body), name.get());
  H5Tinsert(t.get(), FieldOf(event, event.detail).name, offsetof(EventRecord, detail),
            detail.get());
  H5Tinsert(t.get(), FieldOf(event, event.position_mm).name, offsetof(EventRecord, position_mm),
            f3.get());
  Pack(t, packed);
  return t;
}

h5::Handle ConstraintType(bool packed) {
  const SpringConstraint constraint;  // field names from the State field table
  h5::Handle t(H5Tcreate(H5T_COMPOUND, sizeof(ConstraintRecord)), H5Tclose);
  h5::Handle tag = StringType(kTagChars);
  h5::Handle end = EndType(packed);
  H5Tinsert(t.get(), FieldOf(constraint, constraint.id).name, offsetof(ConstraintRecord, id),
            H5T_NATIVE_INT64);
  H5Tinsert(t.get(), FieldOf(constraint, constraint.tag).name, offsetof(ConstraintRecord, tag),
            tag.get());
  H5Tinsert(t.get(), FieldOf(constraint, constraint.stiffness_n_per_mm).name,
            offsetof(ConstraintRecord, stiffness_n_per_mm), H5T_NATIVE_DOUBLE);
  H5Tinsert(t.get(), FieldOf(constraint, constraint.rest_length_mm).name,
            offsetof(ConstraintRecord, rest_length_mm), H5T_NATIVE_DOUBLE);
  H5Tinsert(t.get(), FieldOf(constraint, constraint.slide_friction_n).name,
            offsetof(ConstraintRecord, slide_friction_n), H5T_NATIVE_DOUBLE);
  H5Tinsert(t.get(), FieldOf(constraint, constraint.a).name, offsetof(ConstraintRecord, a),
            end.get());
  H5Tinsert(t.get(), FieldOf(constraint, constraint.b).name, offsetof(ConstraintRecord, b),
            end.get());
  Pack(t, packed);
  return t;
}

h5::Handle ToolContactType(bool packed) {
  const ToolContact contact;  // field names from the State field table
  h5::Handle t(H5Tcreate(H5T_COMPOUND, sizeof(ToolContactRecord)), H5Tclose);
  h5::Handle f3 = ArrayType(H5T_NATIVE_DOUBLE, 3);
  H5Tinsert(t.get(), FieldOf(contact, contact.tool_slot).name,
            offsetof(ToolContactRecord, tool_slot), H5T_NATIVE_INT32);
  H5Tinsert(t.get(), FieldOf(contact, contact.body_kind).name,
            offsetof(ToolContactRecord, body_kind), H5T_NATIVE_UINT8);
  H5Tinsert(t.get(), FieldOf(contact, contact.body).name, offsetof(ToolContactRecord, body),
            H5T_NATIVE_INT32);
  H5Tinsert(t.get(), FieldOf(contact, contact.position_mm).name,
            offsetof(ToolContactRecord, position_mm), f3.get());
  Pack(t, packed);
  return t;
}

std::vector<h5::Group> OrderedGroups(const h5::Group& root, const char* kind) {
  std::vector<h5::Group> out;
  if (!root.Exists(kind)) return out;
  const h5::Group parent = root.OpenGroup(kind);
  std::vector<std::pair<std::int64_t, std::string>> order;
  for (const std::string& n : parent.Children()) {
    order.emplace_back(parent.OpenGroup(n).AttrInt("index"), n);
  }
  std::sort(order.begin(), order.end());  // index, then name: a total order
  for (const auto& [index, name] : order) out.push_back(parent.OpenGroup(name));
  return out;
}

std::string LeafName(const std::string& path) {
  const std::size_t slash = path.rfind('/');
  return slash == std::string::npos ? path : path.substr(slash + 1);
}

void CopyFixed(const std::string& s, char* field, int width) {
  std::memset(field, 0, static_cast<std::size_t>(width));
  std::size_t n = std::min(s.size(), static_cast<std::size_t>(width));
  // Do not split a multi-byte UTF-8 character: back up over continuation bytes (10xxxxxx).
  if (n < s.size()) {
    while (n > 0 && (static_cast<unsigned char>(s[n]) & 0xC0u) == 0x80u) --n;
  }
  std::memcpy(field, s.data(), n);
}

std::string ReadFixed(const char* field, int width) {
  std::size_t n = 0;
  while (n < static_cast<std::size_t>(width) && field[n] != '\0') ++n;
  return std::string(field, n);
}

EventRecord ToRecord(const Event& e) {
  EventRecord r;
  std::memset(&r, 0, sizeof r);  // padding too: records are compared with memcmp
  r.step = e.step;
  r.time_s = e.time_s;
  CopyFixed(e.kind, r.kind, kKindChars);
  CopyFixed(e.tool, r.tool, kNameChars);
  CopyFixed(e.body, r.body, kNameChars);
  CopyFixed(e.detail, r.detail, kDetailChars);
  for (int i = 0; i < 3; ++i) r.position_mm[i] = e.position_mm[i];
  return r;
}

Event FromRecord(const EventRecord& r) {
  Event e;
  e.step = r.step;
  e.time_s = r.time_s;
  e.kind = ReadFixed(r.kind, kKindChars);
  e.tool = ReadFixed(r.tool, kNameChars);
  e.body = ReadFixed(r.body, kNameChars);
  e.detail = ReadFixed(r.detail, kDetailChars);
  e.position_mm = Vec3(r.position_mm[0], r.position_mm[1], r.position_mm[2]);
  return e;
}

namespace {
// Fills an already zeroed record (padding stays zero for memcmp comparisons).
void ToEnd(const ConstraintEnd& e, ConstraintEndRecord& r) {
  r.kind = static_cast<std::uint8_t>(e.kind);
  r.index = e.index;
  for (int i = 0; i < 4; ++i) {
    r.nodes[i] = e.nodes[static_cast<std::size_t>(i)];
    r.weights[i] = e.weights[static_cast<std::size_t>(i)];
  }
  for (int i = 0; i < 3; ++i) r.offset_mm[i] = e.offset_mm[i];
}
ConstraintEnd FromEnd(const ConstraintEndRecord& r) {
  ConstraintEnd e;
  e.kind = static_cast<ConstraintEnd::Kind>(r.kind);
  e.index = r.index;
  for (int i = 0; i < 4; ++i) {
    e.nodes[static_cast<std::size_t>(i)] = r.nodes[i];
    e.weights[static_cast<std::size_t>(i)] = r.weights[i];
  }
  e.offset_mm = Vec3(r.offset_mm[0], r.offset_mm[1], r.offset_mm[2]);
  return e;
}
}  // namespace

ConstraintRecord ToRecord(const SpringConstraint& c) {
  ConstraintRecord r;
  std::memset(&r, 0, sizeof r);
  r.id = c.id;
  CopyFixed(c.tag, r.tag, kTagChars);
  r.stiffness_n_per_mm = c.stiffness_n_per_mm;
  r.rest_length_mm = c.rest_length_mm;
  r.slide_friction_n = c.slide_friction_n;
  ToEnd(c.a, r.a);
  ToEnd(c.b, r.b);
  return r;
}

SpringConstraint FromRecord(const ConstraintRecord& r) {
  SpringConstraint c;
  c.id = r.id;
  c.tag = ReadFixed(r.tag, kTagChars);
  c.stiffness_n_per_mm = r.stiffness_n_per_mm;
  c.rest_length_mm = r.rest_length_mm;
  c.slide_friction_n = r.slide_friction_n;
  c.a = FromEnd(r.a);
  c.b = FromEnd(r.b);
  return c;
}

ToolContactRecord ToRecord(const ToolContact& c) {
  ToolContactRecord r;
  std::memset(&r, 0, sizeof r);
  r.tool_slot = c.tool_slot;
  r.body_kind = static_cast<std::uint8_t>(c.body_kind);
  r.body = c.body;
  for (int i = 0; i < 3; ++i) r.position_mm[i] = c.position_mm[i];
  return r;
}

ToolContact FromRecord(const ToolContactRecord& r) {
  ToolContact c;
  c.tool_slot = r.tool_slot;
  c.body_kind = static_cast<ConstraintEnd::Kind>(r.body_kind);
  c.body = r.body;
  c.position_mm = Vec3(r.position_mm[0], r.position_mm[1], r.position_mm[2]);
  return c;
}

void HoldPositions(const Points& x, double quantum_mm, double tolerance_mm,
                   std::vector<double>* held) {
  const auto n = static_cast<std::size_t>(x.size());
  const double* p = x.data();
  auto round = [quantum_mm](double v) {
    // quantum_mm is a power of two: the division and product are exact.
    return quantum_mm > 0 ? std::nearbyint(v / quantum_mm) * quantum_mm : v;
  };
  if (held->size() != n) {
    held->resize(n);
    for (std::size_t i = 0; i < n; ++i) (*held)[i] = round(p[i]);
    return;
  }
  double* h = held->data();
  for (std::size_t i = 0; i + 2 < n; i += 3) {
    // !(d <= tol) also rewrites a NaN coordinate.
    const bool keep = std::abs(p[i] - h[i]) <= tolerance_mm &&
                      std::abs(p[i + 1] - h[i + 1]) <= tolerance_mm &&
                      std::abs(p[i + 2] - h[i + 2]) <= tolerance_mm;
    if (keep) continue;
    for (std::size_t k = i; k < i + 3; ++k) h[k] = round(p[k]);
  }
}

}  // namespace arthrosim::io::layout
