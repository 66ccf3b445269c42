#pragma once
// Collision geometry of the instruments: the parts of core/instrument_geometry.h (the one
// description that rendering draws too) as rounded simplices for the proximity queries. The
// instruments layer uses the same parts (blade triangles for cutting, burr sphere for bone
// removal...), so there is one definition of where an instrument is.
#include <cstdint>
#include <vector>

#include "arthrosim/collision/proximity.h"
#include "arthrosim/core/instrument_geometry.h"
#include "arthrosim/core/model.h"
#include "arthrosim/core/state.h"

namespace arthrosim::collision {

/// What a primitive is (the parts of core/instrument_geometry.h).
using ToolPart = ::arthrosim::ToolPart;
using ::arthrosim::MaxOpeningDeg;

/// One rounded simplex of an instrument.
struct ToolPrimitive {
  ToolPart part = ToolPart::kShaft;
  std::int32_t side = 0;  ///< 0 = single / upper jaw or blade, 1 = lower
  Simplex core;           ///< mm, tool frame or world depending on the function
  double radius_mm = 0;   ///< rounding: sphere / capsule radius, blade half-thickness
  bool contacts = true;   ///< false: geometry for the instrument logic only
};

/// The primitives of an instrument in the tool frame for a jaw value in [0, 1] (0 open, 1
/// closed). The order and count depend only on the kind, never on jaw (so two poses of the same
/// instrument can be interpolated primitive by primitive).
std::vector<ToolPrimitive> InstrumentPrimitivesLocal(const InstrumentModel& instrument, double jaw);
/// The same into *out (replacing its contents; no allocation once its capacity suffices).
void InstrumentPrimitivesLocal(const InstrumentModel& instrument, double jaw,
                               std::vector<ToolPrimitive>* out);

/// The same primitives in world coordinates for a tool slot state; empty if nothing is inserted.
std::vector<ToolPrimitive> ToolPrimitivesWorld(const Model& model, const ToolState& tool);
/// The same into *out (replacing its contents; no allocation once its capacity suffices).
void ToolPrimitivesWorld(const Model& model, const ToolState& tool,
                         std::vector<ToolPrimitive>* out);

}  // namespace arthrosim::collision
