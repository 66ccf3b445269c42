#pragma once
// The stages of a soft-tissue step that an external time integrator drives (ARKODE through
// ArkodeIntegrator): a narrow interface, so the integrator needs neither SoftSystem's internals
// nor its header. SoftSystem implements it.
//
// The ODE state is y = [x; v] over the SoftSystem slots, 3 entries per slot (x in mm, v in
// mm/s). A step is BeginExternalStep, then any number of EvaluateRates / SolveNewtonSystem
// calls made by the integrator, then FinishExternalStep with the integrator's result.
#include <Eigen/Core>
#include <cstdint>

#include "arthrosim/core/model.h"
#include "arthrosim/core/state.h"
#include "arthrosim/physics/cg_solver.h"
#include "arthrosim/physics/contact.h"

namespace arthrosim::physics {

/// Timings (CPU time of the process, ms: all threads, steady on a shared machine) and solver
/// figures of one Step.
struct SoftStepStats {
  double rotations_ms = 0;  ///< polar rotations + elastic forces
  double assembly_ms = 0;   ///< matrix, preconditioner (incl. any refactorisation), contacts, rhs
  double factor_ms = 0;     ///< part of assembly_ms spent on factor work (a whole factor or a part)
  double solve_ms = 0;      ///< CG
  double update_ms = 0;     ///< integration and write-back to State
  double total_ms = 0;
  int cg_iterations = 0;
  double cg_relative_residual = 0;  ///< final |b - A dv| / max(|b|, h |W|), W the weight
  bool refactored = false;          ///< a new factor came into use this step (built or switched in)
  bool factor_work = false;       ///< this step did factor work (a whole factor or a prepared part)
  bool anchor_moved = false;      ///< this step requested a new factor (State::factor_switch_step)
  std::int32_t active_nodes = 0;  ///< unknown nodes (free, with an element)
  std::int32_t active_tets = 0;   ///< alive, non-degenerate elements
  std::int32_t active_contacts = 0;  ///< penetrating contacts + springs entered in the system
  /// Extra solves for contacts that were apart at the start of the step and crossed within it
  /// (cg_iterations counts all solves).
  int contact_resolves = 0;
};

/// The stage interface an external integrator uses. Vectors are of size 3 * stage_slots().
class SoftStages {
 public:
  /// Slots of the system (a stage vector holds 3 entries per slot).
  virtual std::int32_t stage_slots() const = 0;

  /// Starts a step: fills *x_mm and *v_mm_s with every slot's position and velocity from
  /// `state` (zero for slots without a node).
  virtual void BeginExternalStep(const State& state, Eigen::Ref<Eigen::VectorXd> x_mm,
                                 Eigen::Ref<Eigen::VectorXd> v_mm_s) = 0;

  /// Rates of y = [x; v] at (x, v): dx = v, dv = M^-1 (f(x) - alpha M v - beta K v) on free
  /// slots (f: elastic, gravity, contacts and springs), 0 elsewhere; mm/s and mm/s^2. Fills the
  /// contact and spring terms of the system at x.
  virtual void EvaluateRates(const Model& model, const Eigen::VectorXd& x_mm,
                             const Eigen::VectorXd& v_mm_s, ContactSet* contacts,
                             SpringSet* springs, Eigen::Ref<Eigen::VectorXd> dx,
                             Eigen::Ref<Eigen::VectorXd> dv) = 0;

  /// Solves (I - gamma J) [ox; ov] = [bx; bv], J the Jacobian of the rates linearised at the
  /// positions xz_mm (rotations frozen), gamma in s:
  ///   A ov = M bv - gamma (K + C) bx,  A = (1 + gamma alpha) M + gamma (gamma + beta) K
  ///   + gamma^2 C,  ox = bx + gamma ov on free slots (ox = bx, ov = bv elsewhere),
  /// by the same preconditioned CG as the built-in implicit Euler (model.solver limits).
  virtual CgResult SolveNewtonSystem(const Model& model, double gamma_s,
                                     const Eigen::VectorXd& xz_mm, const Eigen::VectorXd& bx,
                                     const Eigen::VectorXd& bv, ContactSet* contacts,
                                     SpringSet* springs, Eigen::Ref<Eigen::VectorXd> ox,
                                     Eigen::Ref<Eigen::VectorXd> ov) = 0;

  /// Ends a step at the integrator's (x, v) (v_old: the velocities BeginExternalStep gave):
  /// writes positions and velocities of free nodes to `state` (others keep their position with
  /// zero velocity) and the force outputs of the contacts and springs. Returns the node and
  /// contact counts of the step (timings and CG figures are the integrator's to fill).
  virtual SoftStepStats FinishExternalStep(const Model& model, const Eigen::VectorXd& x_mm,
                                           const Eigen::VectorXd& v_mm_s,
                                           const Eigen::VectorXd& v_old_mm_s, ContactSet* contacts,
                                           SpringSet* springs, State* state) = 0;

 protected:
  ~SoftStages() = default;
};

}  // namespace arthrosim::physics
