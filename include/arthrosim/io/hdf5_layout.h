#pragma once
// Names and record types of the run file (docs/hdf5-layout.md), shared by RunWriter, RunReader
// and the XDMF sidecar so that the three cannot drift apart.
#include <cstdint>
#include <string>
#include <type_traits>
#include <vector>

#include "arthrosim/core/state.h"
#include "arthrosim/core/state_fields.h"
#include "arthrosim/io/hdf5.h"

namespace arthrosim::io::layout {

inline constexpr std::int64_t kFormatVersion = 2;  ///< 2: positions as quantised block series
inline constexpr const char* kFormatName = "arthrosim-run";

// Top-level groups. Each body / bone / thread / tool group carries an int attribute "index":
// its position in the Model (HDF5 lists groups alphabetically).
inline constexpr const char* kBodies = "bodies";
inline constexpr const char* kBones = "bones";
inline constexpr const char* kThreads = "threads";
inline constexpr const char* kTools = "tools";
inline constexpr const char* kToolSlots = "tool_slots";
inline constexpr const char* kCamera = "camera";
inline constexpr const char* kConstraints = "constraints";
inline constexpr const char* kToolContacts = "tool_contacts";
inline constexpr const char* kMeta = "meta";

/// The float64 row of a fixed-size record (BoneHole, AnchorState): its members in State field
/// table order (core/state_fields.h), a vector as its three coordinates, anything else cast to
/// double. Appends the row of `record` to *rows.
template <class Record>
void AppendRecordRow(const Record& record, std::vector<double>* rows) {
  VisitFields(record, [&](const auto& member, const FieldInfo&) {
    if constexpr (std::is_same_v<std::decay_t<decltype(member)>, Vec3>) {
      rows->insert(rows->end(), {member.x(), member.y(), member.z()});
    } else {
      rows->push_back(static_cast<double>(member));
    }
  });
}

/// The record of a row written by AppendRecordRow.
template <class Record>
Record RecordFromRow(const double* row) {
  Record record;
  std::size_t i = 0;
  VisitFields(record, [&](auto& member, const FieldInfo&) {
    using M = std::decay_t<decltype(member)>;
    if constexpr (std::is_same_v<M, Vec3>) {
      member = Vec3(row[i], row[i + 1], row[i + 2]);
      i += 3;
    } else {
      member = static_cast<M>(row[i++]);
    }
  });
  return record;
}

/// The number of values in a row written by AppendRecordRow.
template <class Record>
int RecordColumns() {
  std::vector<double> row;
  AppendRecordRow(Record{}, &row);
  return static_cast<int>(row.size());
}

/// Columns of a /holes/rows row: bone, tool_slot, entry xyz (mm), axis xyz, depth (mm),
/// diameter (mm), angle to the surface (deg), open (0/1).
inline const int kHoleColumns = RecordColumns<BoneHole>();
/// Columns of an /anchors/rows row: bone, hole, position xyz (mm), axis xyz, depth below the
/// cortex (mm), insertion angle (deg).
inline const int kAnchorColumns = RecordColumns<AnchorState>();

/// Updates `held` (the stored copy of positions x, 3 x n column-major) to what the next frame
/// stores: every coordinate rounded to a multiple of `quantum_mm` (0: exact); a node keeps its
/// stored value while none of its coordinates differs from it by more than `tolerance_mm`. A
/// new node count rewrites every node. Afterwards every stored coordinate is within
/// max(tolerance_mm, quantum_mm / 2) of x's.
void HoldPositions(const Points& x, double quantum_mm, double tolerance_mm,
                   std::vector<double>* held);

/// Appends the row of a hole (kHoleColumns values) to *rows.
inline void AppendHoleRow(const BoneHole& h, std::vector<double>* rows) {
  AppendRecordRow(h, rows);
}
/// The hole of a row written by AppendHoleRow.
inline BoneHole HoleFromRow(const double* r) { return RecordFromRow<BoneHole>(r); }
/// Appends the row of an anchor (kAnchorColumns values) to *rows.
inline void AppendAnchorRow(const AnchorState& a, std::vector<double>* rows) {
  AppendRecordRow(a, rows);
}
/// The anchor of a row written by AppendAnchorRow.
inline AnchorState AnchorFromRow(const double* r) { return RecordFromRow<AnchorState>(r); }

// Datasets that are not State fields (those take their names from the State field table,
// core/state_fields.h): the event stream, per-entity counts and views derived for readers.
inline constexpr const char* kEvents = "events";
inline constexpr const char* kEventsEnd = "events_end";
inline constexpr const char* kNodeCount = "node_count";
inline constexpr const char* kElementCount = "element_count";
inline constexpr const char* kAliveElements = "alive_elements";
inline constexpr const char* kAliveSegments = "alive_segments";
inline constexpr const char* kActive = "active";  ///< /tools/<instrument>: inserted in a slot
inline constexpr const char* kSlot = "slot";      ///< /tools/<instrument>: the slot holding it
inline constexpr const char* kRows = "rows";      ///< the records of /constraints, /tool_contacts

/// The groups below /<kind> (e.g. "bodies") in Model order (their "index" attribute); empty if
/// the file has no such group.
std::vector<h5::Group> OrderedGroups(const h5::Group& root, const char* kind);
/// Last path component: "/bodies/cuff" -> "cuff".
std::string LeafName(const std::string& path);

/// Suffixes of the two index datasets of a block series `X`: rows X_offset[t] .. +X_count[t]
/// of the concatenated dataset X belong to frame t (a block is written only when it changed;
/// unchanged frames point at the previous block).
inline std::string OffsetName(const std::string& series) { return series + "_offset"; }
inline std::string CountName(const std::string& series) { return series + "_count"; }

// Fixed string widths of the compound records (bytes, NUL-padded; longer text is cut at a UTF-8
// character boundary).
inline constexpr int kKindChars = 32;
inline constexpr int kNameChars = 64;
inline constexpr int kDetailChars = 192;
inline constexpr int kTagChars = 32;

/// One row of /events (memory layout; the file type is the packed equivalent).
struct EventRecord {
  std::int64_t step;
  double time_s;
  char kind[kKindChars];
  char tool[kNameChars];
  char body[kNameChars];
  char detail[kDetailChars];
  double position_mm[3];
};

/// One end of a constraint row.
struct ConstraintEndRecord {
  std::uint8_t kind;  ///< ConstraintEnd::Kind: 0 world, 1 soft body, 2 thread, 3 bone, 4 tool
  std::int32_t index;
  std::int32_t nodes[4];
  double weights[4];
  double offset_mm[3];
};

/// One row of /constraints/rows.
struct ConstraintRecord {
  std::int64_t id;
  char tag[kTagChars];
  double stiffness_n_per_mm;
  double rest_length_mm;
  double slide_friction_n;
  ConstraintEndRecord a;
  ConstraintEndRecord b;
};

/// One row of /tool_contacts/rows.
struct ToolContactRecord {
  std::int32_t tool_slot;
  std::uint8_t body_kind;  ///< ConstraintEnd::Kind
  std::int32_t body;
  double position_mm[3];
};

/// Memory compound type of EventRecord (`packed` = the file type, no padding).
h5::Handle EventType(bool packed);
/// Memory compound type of ConstraintRecord (`packed` = the file type, no padding).
h5::Handle ConstraintType(bool packed);

/// Memory compound type of ToolContactRecord (`packed` = the file type, no padding).
h5::Handle ToolContactType(bool packed);

/// Zero-initialised record of an event (strings cut to their width).
EventRecord ToRecord(const Event& e);
Event FromRecord(const EventRecord& r);
ConstraintRecord ToRecord(const SpringConstraint& c);
SpringConstraint FromRecord(const ConstraintRecord& r);
ToolContactRecord ToRecord(const ToolContact& c);
ToolContact FromRecord(const ToolContactRecord& r);

/// Copies `s` into a NUL-padded field of `width` bytes, cutting at a UTF-8 boundary.
void CopyFixed(const std::string& s, char* field, int width);
/// The text of a NUL-padded field.
std::string ReadFixed(const char* field, int width);

}  // namespace arthrosim::io::layout
