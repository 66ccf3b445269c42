#pragma once
// Names and record types of the run file (docs/hdf5-layout.md), shared by RunWriter, RunReader
// and the XDMF sidecar so that the three cannot drift apart.
#include <cstdint>
#include <string>
#include <vector>

#include "arthrosim/core/state.h"
#include "arthrosim/io/hdf5.h"

namespace arthrosim::io::layout {

inline constexpr std::int64_t kFormatVersion = 1;
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
