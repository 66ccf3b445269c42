// The instrument actions stage: dispatch by instrument kind to one operation per file.
#include "arthrosim/instruments/instruments.h"

#include <array>
#include <cstdio>
#include <string>

#include "arthrosim/instruments/cutting.h"
#include "arthrosim/instruments/soft_shaving.h"
#include "arthrosim/physics/constraints.h"
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

// Name of the body a constraint end is on ("" for a world or tool end).
std::string EndBodyName(const Model& model, const ConstraintEnd& end) {
  const auto i = static_cast<std::size_t>(end.index);
  switch (end.kind) {
    case ConstraintEnd::Kind::kSoftBody:
      return model.soft_bodies[i].name;
    case ConstraintEnd::Kind::kThread:
      return model.threads[i].name;
    case ConstraintEnd::Kind::kBone:
      return model.bones[i].name;
    default:
      return "";
  }
}

// A spring held by a tool cannot outlive the instrument: once a slot is empty (the instrument
// withdrawn), every spring with a tool end on that slot is released, as `release` (`hook_release`
// for the hook's) with reason=withdrawn, in id order.
void ReleaseWithdrawnSlot(const Model& model, int slot, State* state) {
  for (const std::int64_t id :
       physics::FindConstraintsByEnd(*state, ConstraintEnd::Kind::kTool, slot)) {
    const SpringConstraint* c = physics::FindConstraint(*state, id);
    const bool a_is_tool = c->a.kind == ConstraintEnd::Kind::kTool && c->a.index == slot;
    const ConstraintEnd held = a_is_tool ? c->b : c->a;
    const std::string tag = c->tag;
    const Vec3 at = physics::EndPosition(*state, held);
    physics::RemoveConstraint(state, id);
    char detail[128];
    std::snprintf(detail, sizeof detail, "constraint=%lld tag=%s reason=withdrawn",
                  static_cast<long long>(id), tag.c_str());
    RecordEvent(model, slot, tag == "hook" ? "hook_release" : "release", EndBodyName(model, held),
                detail, at, state);
  }
}

}  // namespace

Operation OperationFor(InstrumentKind kind) { return kOperations[static_cast<std::size_t>(kind)]; }

void ApplyInstruments(const Model& model, const StepContext& context, State* state,
                      InstrumentScratch* scratch) {
  for (int slot = 0; slot < kToolSlots; ++slot) {
    const std::int32_t instrument = state->tools[static_cast<std::size_t>(slot)].instrument;
    if (instrument < 0) {
      ReleaseWithdrawnSlot(model, slot, state);
      continue;
    }
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
