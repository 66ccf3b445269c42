#pragma once
// Everything derived from (Model, State) that a step needs: solver structures, collision
// trees, scratch. Not part of State: Build() recreates it from any State (after a restore),
// and a run from a restored State continues bit for bit.
#include "arthrosim/collision/contact_generation.h"
#include "arthrosim/core/model.h"
#include "arthrosim/core/state.h"
#include "arthrosim/instruments/instruments.h"
#include "arthrosim/physics/contact.h"
#include "arthrosim/physics/soft_system.h"
#include "arthrosim/physics/thread_chain.h"
#include "arthrosim/sim/solve_guard.h"
#include "arthrosim/sim/tool_proxy.h"

namespace arthrosim::sim {

/// Per-stage wall-clock timings of the last step (ms) and solver figures, for `bench`.
struct StepTimings {
  double kinematics_ms = 0;
  double collision_ms = 0;
  double soft_ms = 0;
  double thread_ms = 0;
  double instruments_ms = 0;
  double total_ms = 0;
  int substeps = 1;                ///< deformable solves of the step (> 1: a diverged solve redone)
  double max_node_speed_mm_s = 0;  ///< fastest soft-tissue or thread node after the solve
  physics::SoftStepStats soft;
  physics::ThreadStepStats thread;
};

struct Workspace {
  physics::SoftSystem soft;
  physics::ThreadWorkspace threads;
  collision::CollisionParams collision_params;
  collision::CollisionWorld collision;           ///< surfaces and FCL trees, refit every step
  collision::CollisionOutput contacts;           ///< this step's contacts (collision -> solvers)
  collision::ContactEventScratch event_scratch;  ///< work lists of the contact events stage
  physics::SpringSet springs;                    ///< runtime constraints, one per deformable end
  ProxyWorkspace proxy;                          ///< tool proxies: bone trees, work lists
  instruments::InstrumentScratch instrument_scratch;  ///< work lists of the instrument actions
  SolveStart solve_start;  ///< what the deformable solves write, kept to undo a diverged one
  StepTimings timings;
};

/// Builds a workspace for (model, state): call once before stepping and after any restore.
void BuildWorkspace(const Model& model, const State& state, Workspace* ws);

}  // namespace arthrosim::sim
