#pragma once
// The one geometric description of every instrument: each working part is a rounded simplex (a
// sphere, a capsule or a thin triangle with a half-thickness) in the tool frame (tip at the
// origin, shaft along -z, jaws opening in the x-z plane), sized from InstrumentModel and opened
// by the jaw value. Collision (collision/instrument_shape.h) turns the parts into contact
// primitives, rendering draws exactly these parts and the instrument operations act with them
// (blade triangles, burr sphere, awl point), so what the trainee sees is what touches and cuts.
#include <array>
#include <cstdint>

#include "arthrosim/core/model.h"
#include "arthrosim/core/types.h"

namespace arthrosim {

/// What a part is, so instruments can pick their working part.
enum class ToolPart : std::uint8_t {
  kShaft,         ///< capsule along -z behind the working part
  kBlade,         ///< scissors / cutter blade triangle (cutting edge = v0-v1)
  kJaw,           ///< grasper / retriever / scorpion jaw triangle
  kBurr,          ///< burr sphere
  kShaverTip,     ///< shaver outer tube end (capsule)
  kShaverWindow,  ///< shaver cutting window (triangle on the tube side; no contact)
  kCauteryTip,    ///< electrocautery probe (capsule)
  kAwlTip,        ///< awl point (thin capsule)
  kAwlBody,       ///< awl body behind the point (capsule)
  kHook,          ///< crochet hook bend (capsule)
  kPusherTip,     ///< knot-pusher end (capsule)
  kNeedle,        ///< scorpion needle (thin capsule, out only when the jaw is closed)
};

/// One rounded simplex of an instrument in the tool frame: the points within radius_mm of the
/// point (n = 1), segment (n = 2) or triangle (n = 3) spanned by v[0..n).
struct InstrumentPart {
  ToolPart part = ToolPart::kShaft;
  std::int32_t side = 0;  ///< 0 = single / upper jaw or blade, 1 = lower
  int n = 1;              ///< number of core points used
  std::array<Vec3, 3> v{Vec3::Zero(), Vec3::Zero(), Vec3::Zero()};  ///< core points, mm
  double radius_mm = 0;  ///< rounding: sphere / capsule radius, blade half-thickness
  bool contacts = true;  ///< false: geometry for the instrument logic only (never drawn solid)
};

/// At most this many parts per instrument.
inline constexpr int kMaxInstrumentParts = 6;

/// The parts of one instrument (fixed capacity: building them never allocates).
struct InstrumentParts {
  std::array<InstrumentPart, kMaxInstrumentParts> parts;
  int count = 0;
};

/// Maximum opening angle between the two jaws/blades at jaw = 0 (fully open), degrees; 0 for
/// instruments without jaws.
double MaxOpeningDeg(InstrumentKind kind);

/// The parts of an instrument in the tool frame for a jaw value in [0, 1] (0 open, 1 closed).
/// The order and count depend only on the kind, never on jaw (so two poses of the same
/// instrument can be interpolated part by part). The shaft is always the last part.
InstrumentParts InstrumentPartsLocal(const InstrumentModel& instrument, double jaw);

}  // namespace arthrosim
