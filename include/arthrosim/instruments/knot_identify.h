#pragma once
// Knot identification from thread geometry alone: is there a knot in the suture limbs, and which
// (none, half hitch, granny, square, a longer sequence of half hitches)? Pure geometry, usable in
// the step (the knot pusher emits `knot` only for a real knot) and afterwards by scoring on the
// node positions of a run file.
//
// Method (the projected crossing code of knot theory): the open strand is closed by a large arc
// outside a sphere holding every node, so its ends cannot pass through the knot; the closed
// curve is projected along each of 13 directions of its principal frame (the 3 axes, the 6 face
// and the 4 body diagonals), which turns with the thread, so a rotated scene gives the same
// projections; each projection gives a signed Gauss code (the crossings in order along the
// strand: over or under, and the crossing's handedness) that Reidemeister moves I and II (and
// the removal of nugatory crossings) reduce;
// the reduced crossing count and writhe classify the projection, checked by the diagram's knot
// determinant (where they disagree, or the moves cannot simplify the diagram: 1 none, 3 a half
// hitch, else unknown), and the majority of the 13 decides. A half hitch is a trefoil
// (3 crossings, all of one handedness); two half hitches of the same handedness are a granny
// (writhe +-6), of opposite handedness a square knot (writhe 0).
#include <cstdint>
#include <vector>

#include "arthrosim/core/types.h"

namespace arthrosim::instruments {

enum class KnotType : std::uint8_t {
  kNone,         ///< reduces to no crossing: the limbs are not knotted
  kHalfHitch,    ///< one trefoil (an overhand knot)
  kGranny,       ///< two half hitches of the same handedness
  kSquare,       ///< two half hitches of opposite handedness (a reef knot)
  kHalfHitches,  ///< three or more half hitches (3k crossings after reduction, k >= 3)
  kUnknown,      ///< the reduced code fits none of the above
};

/// Lower-case name used in event details and scoring: "none", "half_hitch", "granny", "square",
/// "half_hitches", "unknown".
const char* KnotTypeName(KnotType type);

/// The outcome of identification: the majority class and the projection that represents it.
struct KnotIdentification {
  KnotType type = KnotType::kNone;
  int crossings = 0;     ///< crossings after reduction in a projection of the majority class
  int writhe = 0;        ///< sum of crossing signs (+-1) in that projection
  int half_hitches = 0;  ///< crossings / 3 for the half-hitch classes, else 0
  int votes = 0;         ///< projections that voted for `type`
  int projections = 0;   ///< projections taken (13)
};

/// One crossing passage in a Gauss code: which crossing, whether the strand passes over it, and
/// the crossing's handedness (+1 right-handed, -1 left-handed; the same at both passages).
struct GaussEntry {
  int crossing = 0;
  bool over = false;
  int sign = 0;
};

/// Closes an open strand (>= 2 nodes, mm): straight out from each end, radially from the
/// centroid, to a sphere of three times the largest node distance from the centroid, then along
/// that sphere from the last end's point to the first's. Returns the nodes followed by the
/// closure points (the last point joins the first node). Throws std::invalid_argument for fewer
/// than two nodes or non-finite coordinates.
std::vector<Vec3> CloseStrand(const std::vector<Vec3>& strand);

/// The signed Gauss code of a closed polyline (last point joins the first) seen along
/// `direction` (any non-zero vector; the viewer sits at +direction): entries sorted along the
/// curve from its first point, two per crossing, crossing ids numbered from 0.
std::vector<GaussEntry> GaussCode(const std::vector<Vec3>& closed, const Vec3& direction);

/// Applies Reidemeister move I (a crossing passed twice in a row), its generalisation to
/// nugatory crossings (no other crossing is passed once inside and once outside the loop between
/// a crossing's two passages: the loop untwists) and move II (two crossings of opposite sign
/// passed over-over in a row and under-under in a row) to a cyclic Gauss code until none applies.
void ReduceGaussCode(std::vector<GaussEntry>* code);

/// The knot determinant |Alexander polynomial at -1| of the closed curve whose diagram `code` is
/// (a cyclic signed Gauss code with two passages per crossing): |det| of the colouring matrix
/// with one row and column removed, computed exactly. An invariant: every diagram of a knot gives
/// the same value (unknot 1, trefoil 3, figure-eight 5, granny and square knots 9). Returns -1
/// for a code that is not a knot diagram (a crossing without exactly one over and one under
/// passage) or with more than 48 crossings (its exact arithmetic would not fit 128 bits).
std::int64_t KnotDeterminant(const std::vector<GaussEntry>& code);

/// Identifies the knot in one open strand (node positions in order along the thread, mm).
/// Throws std::invalid_argument as CloseStrand.
KnotIdentification IdentifyKnot(const std::vector<Vec3>& strand);

/// Identifies the knot tied with two limbs that both start at the tissue (node 0 of each limb
/// at the stitch, then outward along the limb): the limbs are joined at their first nodes (the
/// loop through the tissue) into one strand.
KnotIdentification IdentifyKnot(const std::vector<Vec3>& limb_a, const std::vector<Vec3>& limb_b);

}  // namespace arthrosim::instruments
