#pragma once
// Cutting a suture (paper: the cutter removes the nodes from the cut to the end of the thread
// that is not connected to the bone). Nodes are never erased, only marked dead, so State arrays
// keep their size and indices stay valid for output and constraints.
#include "arthrosim/core/model.h"
#include "arthrosim/core/state.h"

namespace arthrosim::physics {

/// Marks nodes [first_node, n) dead (node_alive = 0, velocity 0); returns how many were alive.
/// Throws std::invalid_argument if first_node is outside [0, n).
int CutThreadFrom(ThreadState* state, int first_node);

/// Cuts segment (segment, segment + 1): kills the side that holds no fixed node; if both or
/// neither hold one, kills the side after the segment (higher indices). Returns nodes killed.
int CutThreadAtSegment(const ThreadModel& model, ThreadState* state, int segment);

}  // namespace arthrosim::physics
