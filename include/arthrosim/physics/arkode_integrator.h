#pragma once
// Alternative soft-tissue integrator through SUNDIALS ARKODE (ARKStep): fixed step, fully
// implicit, backward Euler as a 1-stage DIRK table, one Newton iteration per step
// (ARKStepSetLinear) whose linear system is solved by a custom MATRIX_EMBEDDED SUNLinearSolver
// wrapping the same CG, forces and stiffness as the built-in implicit Euler. ODE state
// y = [x; v] over the SoftSystem slots. Selected by SolverOptions::integrator == kArkode.
// It drives the system only through the SoftStages interface (soft_stages.h).
#include <cstdint>

#include "arthrosim/core/model.h"
#include "arthrosim/core/state.h"
#include "arthrosim/physics/contact.h"
#include "arthrosim/physics/soft_stages.h"

namespace arthrosim::physics {

class ArkodeIntegrator {
 public:
  ArkodeIntegrator();
  ~ArkodeIntegrator();
  ArkodeIntegrator(const ArkodeIntegrator&) = delete;
  ArkodeIntegrator& operator=(const ArkodeIntegrator&) = delete;

  /// One step of h_s seconds (model.options.dt_s or a substep of it) for all soft bodies of
  /// `system` (already built). The integrator is re-initialised every step, so the result
  /// depends on State only. Throws std::runtime_error if SUNDIALS reports a failure.
  SoftStepStats Step(SoftStages* system, const Model& model, double h_s, ContactSet* contacts,
                     SpringSet* springs, State* state);

  struct Impl;  // SUNDIALS objects and callback context (public for the C callbacks)

 private:
  Impl* impl_;
};

}  // namespace arthrosim::physics
