// The instrument actions stage: dispatch by instrument kind to one operation per file.
#include "arthrosim/instruments/instruments.h"

#include <array>

#include "arthrosim/instruments/cutting.h"
#include "arthrosim/instruments/soft_shaving.h"
#include "operations.h"
#include "suture_ops.h"

namespace arthrosim::instruments {
namespace {

// One entry per InstrumentKind, in enum order; nullptr = contact only (no operation yet or
// none by design). Each operation lives in its own file and is declared in operations.h.
constexpr std::array<Operation, kInstrumentKindCount> kOperations = {
    &ScissorsCut,              // kScissors
    &ThreadCutter,             // kCutter
    &BurrOperation,            // kBurr
    &ShaverShave,              // kShaver
    &CauteryShave,             // kElectrocautery
    &AwlOperation,             // kAwl
    &RetrieverOperation,       // kRetriever
    &GrasperOperation,         // kGrasper
    &ScorpionNeedleOperation,  // kScorpionNeedle
    &KnotPusherOperation,      // kKnotPusher
    &HookOperation,            // kHook
};

}  // namespace

Operation OperationFor(InstrumentKind kind) { return kOperations[static_cast<std::size_t>(kind)]; }

void ApplyInstruments(const Model& model, const StepContext& context, State* state,
                      InstrumentScratch* scratch) {
  for (int slot = 0; slot < kToolSlots; ++slot) {
    const std::int32_t instrument = state->tools[static_cast<std::size_t>(slot)].instrument;
    if (instrument < 0) continue;
    const Operation op = OperationFor(model.instruments[static_cast<std::size_t>(instrument)].kind);
    if (op != nullptr) op(model, slot, context, state, scratch);
  }
}

void RecordEvent(const Model& model, int slot, const char* kind, const std::string& body,
                 const std::string& detail, const Vec3& position_mm, State* state) {
  const std::int32_t instrument = state->tools[static_cast<std::size_t>(slot)].instrument;
  const std::string tool =
      instrument >= 0 ? model.instruments[static_cast<std::size_t>(instrument)].name : "";
  state->events.push_back(Event{state->step, state->time_s, kind, tool, body, detail, position_mm});
}

}  // namespace arthrosim::instruments
