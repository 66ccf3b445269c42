#pragma once
// The operations registered in the dispatch table of instruments.cpp, one file each.
#include "arthrosim/instruments/instruments.h"

namespace arthrosim::instruments {

/// Burr (burr.cpp): removes bone around the burr head while button 1 is held in contact.
void BurrOperation(const Model& model, int slot, const StepContext& context, State* state,
                   InstrumentScratch* scratch);

/// Awl (awl_drill.cpp): makes and deepens a pilot hole; button 2 seats an anchor in it
/// (anchor.cpp).
void AwlOperation(const Model& model, int slot, const StepContext& context, State* state,
                  InstrumentScratch* scratch);

/// The hole an anchor would be seated in for an awl tip at `tip` (mm): deep enough, without an
/// anchor, its axis segment within operations.anchor.capture_radius_mm of the tip (nearest
/// wins); -1 if none.
int HoleForAnchor(const Model& model, const Vec3& tip, const State& state);

/// Seats an anchor at the bottom of hole `hole` for tool slot `slot` (anchor.cpp): appends
/// State::anchors, lays the anchor's sutures and holds them to it, records an `anchor` event.
void SeatAnchor(const Model& model, int slot, int hole, State* state);

}  // namespace arthrosim::instruments
