#pragma once
// The instrument actions stage of a step: what each instrument does to tissue, bone and suture
// while its control is applied (Choi et al. 2020, section III and Table 1). It runs after the
// solvers, when this step's contacts carry their solved forces, and edits State: tets removed or
// split, bone reshaped, thread nodes cut, constraints made or released, events recorded. The
// edits take effect in the next step (SyncWorld rebuilds what changed, constraints become
// springs), staggered as constraints already are.
//
// Layering: instruments include core, mesh, physics and collision only (never sim, io, input,
// render); the soft solver is passed in because topology edits must update its derived data.
// One file per operation in src/instruments/, each a function of
// (Model, slot, this step's context, State*, scratch) registered in the dispatch table of
// instruments.cpp by InstrumentKind.
#include <array>
#include <cstdint>
#include <vector>

#include "arthrosim/collision/contact_generation.h"
#include "arthrosim/collision/tet_query.h"
#include "arthrosim/core/model.h"
#include "arthrosim/core/state.h"
#include "arthrosim/physics/soft_system.h"

namespace arthrosim::instruments {

/// What an operation may read of this step besides State: the solved contacts (force_n filled
/// by the solvers) and the collision world (surfaces and trees as of this step's detection).
struct StepContext {
  const collision::CollisionOutput* contacts = nullptr;
  const collision::CollisionWorld* world = nullptr;
  physics::SoftSystem* soft = nullptr;  ///< topology edits (RemoveTets, SplitTet, ...) go here
  /// The tool slots as they were before this step's commands (jaw closing = jaw grew).
  const std::array<ToolState, kToolSlots>* prev_tools = nullptr;
};

/// Work lists the operations reuse from step to step (Workspace; never part of State).
struct InstrumentScratch {
  std::vector<std::int32_t> tets;                    ///< element indices an operation selected
  std::vector<std::int32_t> nodes;                   ///< node indices an operation selected
  Points points;                                     ///< 3 x N positions an operation computed
  std::vector<collision::TetTree> tet_trees;         ///< per soft body: element tree for blade cuts
  std::vector<collision::ToolPrimitive> primitives;  ///< an instrument's parts in world frame
};

/// Control state of a tool slot as the operations read it.
inline bool Button1(const ToolState& tool) { return (tool.buttons & 1u) != 0; }
inline bool Button2(const ToolState& tool) { return (tool.buttons & 2u) != 0; }

/// The stage: for every tool slot holding an instrument, runs that instrument kind's operation
/// (kinds without one only make contacts). Slots run in index order, so the result does not
/// depend on thread count or timing. Events are stamped with state->step and state->time_s: call
/// after the clock has advanced, so they carry the step whose state shows their effect.
void ApplyInstruments(const Model& model, const StepContext& context, State* state,
                      InstrumentScratch* scratch);

/// An operation: acts for tool slot `slot` (holding an instrument of its kind) on State.
using Operation = void (*)(const Model& model, int slot, const StepContext& context, State* state,
                           InstrumentScratch* scratch);

/// The operation registered for a kind, or nullptr if that kind only makes contacts.
Operation OperationFor(InstrumentKind kind);

/// Appends an event of this step (stamped with state->step and state->time_s) for tool slot
/// `slot`: kind ("cut", "burr", ...), the body it touched ("" = none), free-text detail
/// ("key=value" pairs separated by spaces) and a position, mm.
void RecordEvent(const Model& model, int slot, const char* kind, const std::string& body,
                 const std::string& detail, const Vec3& position_mm, State* state);

}  // namespace arthrosim::instruments
