#include "arthrosim/sim/tool_kinematics.h"

#include <algorithm>
#include <string>

#include "arthrosim/core/error.h"

namespace arthrosim::sim {
namespace {

std::string InstrumentName(const Model& model, std::int32_t index) {
  return index >= 0 ? model.instruments[static_cast<std::size_t>(index)].name : std::string();
}

}  // namespace

void ApplyToolCommands(const Model& model, const InputFrame& input, State* state) {
  const auto count = static_cast<std::int32_t>(model.instruments.size());
  for (int slot = 0; slot < kToolSlots; ++slot) {
    const ToolCommand& cmd = input.tools[slot];
    ToolState& tool = state->tools[slot];
    if (cmd.instrument < -1 || cmd.instrument >= count) {
      throw InputError(
          "", 0, "slot" + std::to_string(slot) + ".instrument",
          "instrument index " + std::to_string(cmd.instrument) + " is not in the scenario");
    }
    if (cmd.instrument != tool.instrument) {
      // Events carry the step and time of the state they belong to: the end of this step.
      const std::int64_t step = state->step + 1;
      state->events.push_back(Event{
          step, static_cast<double>(step) * model.options.dt_s, "tool_change",
          InstrumentName(model, cmd.instrument), "",
          "slot" + std::to_string(slot) + " from '" + InstrumentName(model, tool.instrument) + "'",
          cmd.pose.position_mm});
      tool.instrument = cmd.instrument;
    }
    tool.handle_pose = cmd.pose;  // the proxy stage moves tool.pose after it
    tool.handle_pose.orientation.normalize();
    tool.jaw = std::clamp(cmd.jaw, 0.0, 1.0);
    tool.buttons = cmd.buttons;
  }
  state->camera.pose = input.camera.pose;
  state->camera.pose.orientation.normalize();
  state->camera.lens_roll_rad = input.camera.lens_roll_rad;
  state->camera.head_roll_rad = input.camera.head_roll_rad;
}

}  // namespace arthrosim::sim
