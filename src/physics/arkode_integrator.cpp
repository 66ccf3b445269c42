#include "arthrosim/physics/arkode_integrator.h"

#include <arkode/arkode_arkstep.h>
#include <arkode/arkode_butcher.h>
#include <nvector/nvector_serial.h>
#include <sundials/sundials_context.h>
#include <sundials/sundials_linearsolver.h>

#include <chrono>
#include <stdexcept>
#include <string>

#include "arthrosim/physics/cg_solver.h"
#include "arthrosim/physics/soft_stages.h"

namespace arthrosim::physics {

struct ArkodeIntegrator::Impl {
  SUNContext ctx = nullptr;
  void* ark = nullptr;
  N_Vector y = nullptr;
  SUNLinearSolver ls = nullptr;
  sunindextype size = 0;
  // Context of the current step, read by the callbacks.
  SoftStages* sys = nullptr;
  const Model* model = nullptr;
  ContactSet* contacts = nullptr;
  SpringSet* springs = nullptr;
  int cg_iterations = 0;
  double cg_residual = 0;
  double solve_ms = 0;

  ~Impl() { Release(); }
  void Release() {
    if (ark) ARKStepFree(&ark);
    if (y) N_VDestroy(y);
    if (ls) SUNLinSolFreeEmpty(ls);
    if (ctx) SUNContext_Free(&ctx);
    ark = nullptr;
    y = nullptr;
    ls = nullptr;
    ctx = nullptr;
  }
};

namespace {

void Check(int flag, const char* what) {
  if (flag < 0)
    throw std::runtime_error(std::string("ARKODE: ") + what + " failed, flag " +
                             std::to_string(flag));
}

Eigen::Map<Eigen::VectorXd> Part(N_Vector v, Eigen::Index half, int which) {
  return Eigen::Map<Eigen::VectorXd>(N_VGetArrayPointer(v) + which * half, half);
}

}  // namespace

// The C callbacks of ARKODE and of the custom linear solver, on the SoftStages interface.
struct ArkodeBridge {
  // ydot = [v; M^-1 (f(x) - alpha M v - beta K v)] on free slots, 0 elsewhere.
  static int Rhs(sunrealtype, N_Vector y, N_Vector ydot, void* data) {
    auto* im = static_cast<ArkodeIntegrator::Impl*>(data);
    const Eigen::Index half = 3 * im->sys->stage_slots();
    const Eigen::VectorXd x = Part(y, half, 0);
    const Eigen::VectorXd v = Part(y, half, 1);
    im->sys->EvaluateRates(*im->model, x, v, im->contacts, im->springs, Part(ydot, half, 0),
                           Part(ydot, half, 1));
    return 0;
  }

  // (I - gamma J) [dx; dv] = [bx; bv] with J the Jacobian of Rhs (rotations frozen): the same
  // system as the built-in implicit Euler with h = gamma (SoftStages::SolveNewtonSystem).
  static int Solve(SUNLinearSolver ls, SUNMatrix, N_Vector x, N_Vector b, sunrealtype) {
    auto* im = static_cast<ArkodeIntegrator::Impl*>(ls->content);
    const auto t0 = std::chrono::steady_clock::now();
    sunrealtype tcur = 0, gamma = 0;
    N_Vector zpred = nullptr, z = nullptr, fi = nullptr, sdata = nullptr;
    void* user = nullptr;
    // MATRIX_EMBEDDED: ARKLS never calls setup, so (re)linearise here at the current iterate.
    if (ARKStepGetNonlinearSystemData(im->ark, &tcur, &zpred, &z, &fi, &gamma, &sdata, &user) < 0)
      return -1;
    const Eigen::Index half = 3 * im->sys->stage_slots();
    const Eigen::VectorXd xz = Part(z, half, 0);
    const Eigen::VectorXd bx = Part(b, half, 0);
    const Eigen::VectorXd bv = Part(b, half, 1);
    const CgResult cg = im->sys->SolveNewtonSystem(*im->model, gamma, xz, bx, bv, im->contacts,
                                                   im->springs, Part(x, half, 0), Part(x, half, 1));
    im->cg_iterations += cg.iterations;
    im->cg_residual = cg.relative_residual;
    im->solve_ms +=
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    return cg.converged || cg.iterations >= im->model->solver.cg_max_iterations ? 0 : 1;
  }

  static SUNLinearSolver_Type Type(SUNLinearSolver) { return SUNLINEARSOLVER_MATRIX_EMBEDDED; }
  static SUNLinearSolver_ID Id(SUNLinearSolver) { return SUNLINEARSOLVER_CUSTOM; }
  static int NumIters(SUNLinearSolver ls) {
    return static_cast<ArkodeIntegrator::Impl*>(ls->content)->cg_iterations;
  }
  static sunrealtype ResNorm(SUNLinearSolver ls) {
    return static_cast<ArkodeIntegrator::Impl*>(ls->content)->cg_residual;
  }
  static int Free(SUNLinearSolver) { return 0; }  // owned by Impl
};

ArkodeIntegrator::ArkodeIntegrator() : impl_(new Impl) {}
ArkodeIntegrator::~ArkodeIntegrator() { delete impl_; }

SoftStepStats ArkodeIntegrator::Step(SoftStages* system, const Model& model, double h_s,
                                     ContactSet* contacts, SpringSet* springs, State* state) {
  using Clock = std::chrono::steady_clock;
  const auto t_start = Clock::now();
  Impl& im = *impl_;
  const Eigen::Index half = 3 * system->stage_slots();
  const sunindextype n = 2 * static_cast<sunindextype>(half);
  const double h = h_s;
  if (im.size != n) {
    im.Release();
    Check(SUNContext_Create(nullptr, &im.ctx), "SUNContext_Create");
    im.y = N_VNew_Serial(n, im.ctx);
    im.ls = SUNLinSolNewEmpty(im.ctx);
    im.ls->content = &im;
    im.ls->ops->gettype = ArkodeBridge::Type;
    im.ls->ops->getid = ArkodeBridge::Id;
    im.ls->ops->solve = ArkodeBridge::Solve;
    im.ls->ops->numiters = ArkodeBridge::NumIters;
    im.ls->ops->resnorm = ArkodeBridge::ResNorm;
    im.ls->ops->free = ArkodeBridge::Free;
    im.size = n;
  }
  system->BeginExternalStep(*state, Part(im.y, half, 0), Part(im.y, half, 1));
  const Eigen::VectorXd v_old = Part(im.y, half, 1);
  // A fresh integrator every step: nothing but State carries over (restore-safe).
  if (im.ark) ARKStepFree(&im.ark);
  im.ark = ARKStepCreate(nullptr, ArkodeBridge::Rhs, state->time_s, im.y, im.ctx);
  if (!im.ark) throw std::runtime_error("ARKODE: ARKStepCreate failed");
  const sunrealtype c[1] = {1}, a[1] = {1}, bw[1] = {1};
  ARKodeButcherTable be =
      ARKodeButcherTable_Create(1, 1, 0, const_cast<sunrealtype*>(c), const_cast<sunrealtype*>(a),
                                const_cast<sunrealtype*>(bw), nullptr);
  Check(ARKStepSetTables(im.ark, 1, 0, be, nullptr), "ARKStepSetTables");
  ARKodeButcherTable_Free(be);
  Check(ARKStepSetUserData(im.ark, &im), "ARKStepSetUserData");
  Check(ARKStepSStolerances(im.ark, 1e-6, 1e-9), "ARKStepSStolerances");
  Check(ARKStepSetFixedStep(im.ark, h), "ARKStepSetFixedStep");
  Check(ARKStepSetLinearSolver(im.ark, im.ls, nullptr), "ARKStepSetLinearSolver");
  Check(ARKStepSetLinear(im.ark, 0), "ARKStepSetLinear");  // one Newton iteration (as SOFA)
  Check(ARKStepSetDeduceImplicitRhs(im.ark, SUNTRUE), "ARKStepSetDeduceImplicitRhs");
  Check(ARKStepSetPredictorMethod(im.ark, 0), "ARKStepSetPredictorMethod");  // z0 = y_n
  im.sys = system;
  im.model = &model;
  im.contacts = contacts;
  im.springs = springs;
  im.cg_iterations = 0;
  im.cg_residual = 0;
  im.solve_ms = 0;
  sunrealtype t = state->time_s;
  Check(ARKStepEvolve(im.ark, state->time_s + h, im.y, &t, ARK_ONE_STEP), "ARKStepEvolve");

  const Eigen::VectorXd x_end = Part(im.y, half, 0);
  const Eigen::VectorXd v_end = Part(im.y, half, 1);
  SoftStepStats stats =
      system->FinishExternalStep(model, x_end, v_end, v_old, contacts, springs, state);
  stats.cg_iterations = im.cg_iterations;
  stats.cg_relative_residual = im.cg_residual;
  stats.solve_ms = im.solve_ms;
  stats.total_ms = std::chrono::duration<double, std::milli>(Clock::now() - t_start).count();
  return stats;
}

}  // namespace arthrosim::physics
