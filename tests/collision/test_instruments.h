#pragma once
// Instruments for the hand-built collision test scenes.
#include <string>

#include "arthrosim/core/model.h"

namespace arthrosim::collision::testing {

/// An instrument named `name` of `kind` with the given tip radius, every other field default.
inline InstrumentModel TipInstrument(const std::string& name, InstrumentKind kind,
                                     double tip_radius_mm) {
  InstrumentModel m;
  m.name = name;
  m.kind = kind;
  m.tip_radius_mm = tip_radius_mm;
  return m;
}

}  // namespace arthrosim::collision::testing
