// The step, as a table of contents: each stage is one named function below, in order.
#include "arthrosim/sim/step.h"

#include <fmt/core.h>

#include <algorithm>
#include <chrono>

#include "arthrosim/core/units.h"
#include "arthrosim/instruments/instruments.h"
#include "arthrosim/physics/constraints.h"
#include "arthrosim/sim/solve_guard.h"
#include "arthrosim/sim/tool_kinematics.h"
#include "arthrosim/sim/tool_proxy.h"

namespace arthrosim::sim {
namespace {

using Clock = std::chrono::steady_clock;
double MsSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

// Events describe one step only.
void BeginStep(State* state) { state->events.clear(); }

// Tool proxies: each instrument follows its handle along the swept path but stays outside bone,
// sliding along it (god-object); the bone touches join the contact events after detection.
void ResolveToolProxies(const Model& model, const std::array<ToolState, kToolSlots>& prev_tools,
                        State* state, Workspace* ws) {
  sim::ResolveToolProxies(model, prev_tools, state, &ws->proxy);
}

// Collision: contacts of tools, tissue, thread and bone at the start of the step, with the
// tool sweep from last step's pose (no tunnelling).
void DetectContacts(const Model& model, const State& state,
                    const std::array<ToolState, kToolSlots>& prev_tools, Workspace* ws) {
  const auto t0 = Clock::now();
  collision::Detect(model, state, prev_tools, ws->collision_params, &ws->collision, &ws->contacts);
  std::vector<ToolContact>& touches = ws->contacts.bone_touches;
  for (const ToolContact& t : ws->proxy.touches) {
    const bool known = std::any_of(touches.begin(), touches.end(), [&](const ToolContact& c) {
      return c.tool_slot == t.tool_slot && c.body == t.body;
    });
    if (!known) touches.push_back(t);
  }
  ws->timings.collision_ms = MsSince(t0);
}

// Runtime constraints (grasps, stitches, knots, anchors) become springs for the solvers, each
// deformable end anchored at the other end's start-of-step position (staggered coupling).
void BuildConstraintSprings(const State& state, Workspace* ws) {
  physics::BuildPointSprings(state, &ws->springs);
}

// Soft tissue: one linearised implicit Euler (sub)step of h_s of every soft body (FEM + CG).
physics::SoftStepStats SolveSoftTissue(const Model& model, double h_s, State* state,
                                       Workspace* ws) {
  const auto t0 = Clock::now();
  ws->timings.soft = ws->soft.Advance(model, h_s, &ws->contacts.contacts, &ws->springs, state);
  ws->timings.soft_ms += MsSince(t0);
  return ws->timings.soft;
}

// Suture threads: implicit mass-spring chains with self-collision and the speed cap.
void SolveThreads(const Model& model, double h_s, State* state, Workspace* ws) {
  const auto t0 = Clock::now();
  physics::StepThreads(model.threads, h_s, model.options.gravity_mm_s2, &ws->contacts.contacts,
                       &ws->springs, &state->threads, &ws->threads);
  ws->timings.thread = ws->threads.last;
  ws->timings.thread_ms += MsSince(t0);
}

// Records that this step's solve diverged and is redone in `substeps` substeps.
void RecordSolverRetry(const Model& model, const SolveHealth& health, int substeps, State* state) {
  state->events.push_back(
      Event{state->step + 1, state->time_s + model.options.dt_s, "solver_retry", "",
            WorstNodeBody(model, health),
            fmt::format("substeps={} node={} speed_mm_s={:.6g} finite={}", substeps, health.node,
                        health.max_speed_mm_s, health.finite ? 1 : 0),
            Vec3::Zero()});
}

// Soft tissue and threads over the step, guarded against divergence: a solve that leaves a
// non-finite value or a node faster than solver.divergence_speed is undone and done again in
// 2, 4, ... substeps from the same start (contacts detected afresh), with a `solver_retry`
// event; a step that diverges even in solver.divergence_max_substeps substeps is undone and
// stops the run (SimulationError). The preconditioner factor is requested only once the step
// is sound. docs/numerical-guards.md.
void SolveDeformables(const Model& model, const std::array<ToolState, kToolSlots>& prev_tools,
                      State* state, Workspace* ws) {
  ws->timings.soft_ms = 0;
  ws->timings.thread_ms = 0;
  SaveSolveStart(*state, &ws->solve_start);
  for (int substeps = 1;; substeps *= 2) {
    const double h = model.options.dt_s / substeps;
    bool factor_due = false;
    physics::SoftStepStats soft;
    for (int k = 0; k < substeps; ++k) {
      soft = SolveSoftTissue(model, h, state, ws);
      factor_due = factor_due || soft.anchor_moved;
      SolveThreads(model, h, state, ws);
    }
    const SolveHealth health = CheckSolve(*state);
    ws->timings.substeps = substeps;
    ws->timings.max_node_speed_mm_s = health.max_speed_mm_s;
    if (!health.Diverged(model)) {
      soft.anchor_moved = factor_due;
      ws->soft.RequestFactorAfter(soft, state);
      return;
    }
    RestoreSolveStart(ws->solve_start, state);
    if (2 * substeps > model.solver.divergence_max_substeps) {
      throw SimulationError(
          state->step + 1,
          fmt::format("step {} (t = {:.4f} s): the deformable solve diverged ({}) even in {} "
                      "substeps (solver.divergence_max_substeps); the state is kept as at the "
                      "step's start",
                      state->step + 1, state->time_s + model.options.dt_s,
                      DescribeWorstNode(model, health), substeps));
    }
    RecordSolverRetry(model, health, 2 * substeps, state);
    DetectContacts(model, *state, prev_tools, ws);  // contact outputs of the undone solve reset
    BuildConstraintSprings(*state, ws);
  }
}

// Sliding constraint ends: threads run through stitches, knots and the hook's bend where the
// pull along them exceeds the friction (Coulomb); the new points hold from the next step.
void SlideConstraints(State* state) { physics::SlideConstraintEnds(state); }

// Forces on the instruments (haptic feedback, /tools/<name>/force): the handle-proxy coupling,
// the reactions of the solved contacts and those of springs held by a tool (a grasp pulls back
// on the grasper), clamped to the device maximum.
void AccumulateToolForces(const Model& model, const std::array<ToolState, kToolSlots>& prev_tools,
                          const Workspace& ws, State* state) {
  std::array<Vec3, kToolSlots> f = collision::ToolForces(ws.contacts);
  for (const physics::PointSpring& spring : ws.springs) {
    const SpringConstraint* c = physics::FindConstraint(*state, spring.constraint_id);
    if (c == nullptr) continue;
    // The spring acts on one deformable end; the tool at the other end feels the opposite.
    for (const ConstraintEnd* end : {&c->a, &c->b}) {
      if (end->kind == ConstraintEnd::Kind::kTool && end->index >= 0 && end->index < kToolSlots) {
        f[static_cast<std::size_t>(end->index)] -= spring.force_n;
      }
    }
  }
  for (int slot = 0; slot < kToolSlots; ++slot) {
    ToolState& tool = state->tools[slot];
    const Vec3 coupling = CouplingForce(model, prev_tools[slot], tool);
    tool.tissue_force_n = f[slot];
    tool.force_n = ClampForce(f[slot] + coupling, model.haptics.max_force_n);
  }
}

// Contact start/end events, by comparing this step's touching pairs with the last step's.
void RecordContactEvents(const Model& model, Workspace* ws, State* state) {
  collision::UpdateContactEvents(model, *state, ws->contacts, &state->tool_contacts, &state->events,
                                 &ws->event_scratch);
}

// Clock: step index and time are derived from the index so they never drift.
void AdvanceTime(const Model& model, State* state) {
  state->step += 1;
  state->time_s = static_cast<double>(state->step) * model.options.dt_s;
}

// Instrument actions: what each instrument does while its control is applied (cut, shave,
// drill, grasp, suture, tie), with this step's solved contacts. Edits take effect next step.
void ApplyInstrumentActions(const Model& model, const std::array<ToolState, kToolSlots>& prev_tools,
                            Workspace* ws, State* state) {
  const auto t0 = Clock::now();
  const instruments::StepContext context{&ws->contacts, &ws->collision, &ws->soft, &prev_tools};
  instruments::ApplyInstruments(model, context, state, &ws->instrument_scratch);
  ws->timings.instruments_ms = MsSince(t0);
}

}  // namespace

void BuildWorkspace(const Model& model, const State& state, Workspace* ws) {
  ws->soft.Build(model, state);
  ws->threads.params = model.thread_solver;  // scenario `thread_solver:`
  physics::InitThreadWorkspace(model.threads, &ws->threads);
  ws->collision_params = collision::ParamsFromModel(model.contact);  // scenario `contact:`
  ws->collision = collision::CollisionWorld{};
  ws->proxy = ProxyWorkspace{};
  collision::SyncWorld(model, state, &ws->collision);
}

void Step(const Model& model, const InputFrame& input, State* state, Workspace* ws) {
  const auto t0 = Clock::now();
  BeginStep(state);
  const std::array<ToolState, kToolSlots> prev_tools = state->tools;
  ApplyToolCommands(model, input, state);
  ResolveToolProxies(model, prev_tools, state, ws);
  ws->timings.kinematics_ms = MsSince(t0);
  DetectContacts(model, *state, prev_tools, ws);
  BuildConstraintSprings(*state, ws);
  SolveDeformables(model, prev_tools, state, ws);
  SlideConstraints(state);
  AccumulateToolForces(model, prev_tools, *ws, state);
  AdvanceTime(model, state);
  RecordContactEvents(model, ws, state);
  ApplyInstrumentActions(model, prev_tools, ws, state);
  ws->timings.total_ms = MsSince(t0);
}

FeedbackFrame Feedback(const State& state) {
  FeedbackFrame f;
  for (int slot = 0; slot < kToolSlots; ++slot) f.force_n[slot] = state.tools[slot].force_n;
  return f;
}

}  // namespace arthrosim::sim
