#pragma once
// The divergence guard of the deformable solves (docs/numerical-guards.md): what the soft and
// thread solvers write is kept at the start of the solve, the result is checked (finite, no
// node faster than solver.divergence_speed), and a diverged solve is undone so that the step
// can be solved again in substeps.
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "arthrosim/core/model.h"
#include "arthrosim/core/state.h"

namespace arthrosim::sim {

/// A step that diverged even in solver.divergence_max_substeps substeps. The state is left as
/// at the start of the solve (finite); the run cannot continue. The CLI maps it to exit 3.
class SimulationError : public std::runtime_error {
 public:
  SimulationError(std::int64_t step, const std::string& message)
      : std::runtime_error(message), step_(step) {}
  /// The step that could not be solved (State::step + 1 of the state it started from).
  std::int64_t step() const { return step_; }

 private:
  std::int64_t step_ = 0;
};

/// What the solvers write in State, copied at the start of a step's solve: positions,
/// velocities and warm starts of soft bodies and threads. The copies keep their storage, so a
/// step allocates only when a body has grown.
struct SolveStart {
  std::vector<Points> soft_x, soft_v, soft_dv_warm;
  std::vector<Points> thread_x, thread_v;
};

/// Copies what the deformable solves write from `state` into *start.
void SaveSolveStart(const State& state, SolveStart* start);
/// Puts back what SaveSolveStart copied (nodes appended since are not touched).
void RestoreSolveStart(const SolveStart& start, State* state);

/// The verdict on a solve: the fastest node of the soft bodies and threads, and the first
/// node with a non-finite position or velocity if any.
struct SolveHealth {
  bool finite = true;
  double max_speed_mm_s = 0;
  ConstraintEnd::Kind kind = ConstraintEnd::Kind::kSoftBody;  ///< kSoftBody or kThread
  std::int32_t body = -1;  ///< body or thread index of the worst node (-1: no node at all)
  std::int32_t node = -1;
  /// Diverged: a non-finite value, or a node faster than model.solver.divergence_speed_mm_s.
  bool Diverged(const Model& model) const {
    return !finite || max_speed_mm_s > model.solver.divergence_speed_mm_s;
  }
};

/// Checks every node of every soft body and thread of `state` (no allocation).
SolveHealth CheckSolve(const State& state);

/// Name of the soft body or thread of the worst node ("" when there is no node).
std::string WorstNodeBody(const Model& model, const SolveHealth& health);

/// "soft body 'tendon' node 17 at 1.2e+05 mm/s" / "... node 17 not finite": for events and
/// messages.
std::string DescribeWorstNode(const Model& model, const SolveHealth& health);

}  // namespace arthrosim::sim
