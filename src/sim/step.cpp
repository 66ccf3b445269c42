// The step, as a table of contents: each stage is one named function below, in order.
#include "arthrosim/sim/step.h"

#include <algorithm>
#include <chrono>

#include "arthrosim/core/units.h"
#include "arthrosim/instruments/instruments.h"
#include "arthrosim/physics/constraints.h"
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

// Soft tissue: one linearised implicit Euler step of every soft body (FEM + CG).
void SolveSoftTissue(const Model& model, State* state, Workspace* ws) {
  const auto t0 = Clock::now();
  ws->timings.soft = ws->soft.Step(model, &ws->contacts.contacts, &ws->springs, state);
  ws->timings.soft_ms = MsSince(t0);
}

// Suture threads: implicit mass-spring chains with self-collision and the speed cap.
void SolveThreads(const Model& model, State* state, Workspace* ws) {
  const auto t0 = Clock::now();
  physics::StepThreads(model.threads, model.options.dt_s, model.options.gravity_mm_s2,
                       &ws->contacts.contacts, &ws->springs, &state->threads, &ws->threads);
  ws->timings.thread = ws->threads.last;
  ws->timings.thread_ms = MsSince(t0);
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
  SolveSoftTissue(model, state, ws);
  SolveThreads(model, state, ws);
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
