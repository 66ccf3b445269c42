#pragma once
// The fixed-step core: state(t) + input(t) -> state(t + dt). Deterministic: the same model,
// state and input give a bit-identical state, for any thread count.
#include "arthrosim/core/input_frame.h"
#include "arthrosim/core/model.h"
#include "arthrosim/core/state.h"
#include "arthrosim/sim/workspace.h"

namespace arthrosim::sim {

/// Advances *state by model.options.dt_s. ws must have been built for (model, *state).
/// @throws InputError if the input names something the model does not have.
void Step(const Model& model, const InputFrame& input, State* state, Workspace* ws);

/// Contact force on each tool slot after the last step (N), for haptic feedback.
FeedbackFrame Feedback(const State& state);

}  // namespace arthrosim::sim
