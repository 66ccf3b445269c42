#pragma once
// Stage 1 of a step: instruments and scope follow the input frame. Exchanges (an instrument
// inserted, withdrawn or swapped in a slot) become tool_change events.
#include "arthrosim/core/input_frame.h"
#include "arthrosim/core/model.h"
#include "arthrosim/core/state.h"

namespace arthrosim::sim {

/// Copies the commanded poses (into ToolState::handle_pose; the proxy stage then moves
/// ToolState::pose), jaws and buttons into State; validates instrument indices.
/// @throws InputError if a command names an instrument index outside the Model.
void ApplyToolCommands(const Model& model, const InputFrame& input, State* state);

}  // namespace arthrosim::sim
