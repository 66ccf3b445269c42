// The divergence guard (sim/solve_guard.h, the SolveDeformables stage of the step): abuse that
// a trainee, a device or a scenario can bring (a tool teleporting through tissue, a modulus of
// 1 Pa or 1 GPa, a 0.1 s step, a thread pulled at 1 kN) never leaves a non-finite or runaway
// state: a diverged solve is redone in substeps (a `solver_retry` event) or stops the run with
// a SimulationError that names the node, with the state as at the step's start.
#include "arthrosim/sim/solve_guard.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <limits>

#include "arthrosim/io/scenario_loader.h"
#include "arthrosim/physics/constraints.h"
#include "arthrosim/sim/step.h"

namespace arthrosim::sim {
namespace {

Model SmallModel() {
  return io::LoadScenario(std::string(ARTHROSIM_SOURCE_DIR) + "/tests/testdata/scenes/small.yaml");
}

// The grasper through slot 0 at `x` (mm), jaw open.
InputFrame GrasperAt(const Model& m, const Vec3& x) {
  InputFrame f;
  f.camera.pose = m.camera.initial_pose;
  f.tools[0].instrument = m.FindInstrument("grasper");
  f.tools[0].pose.position_mm = x;
  return f;
}

struct Outcome {
  int steps = 0;         // steps completed
  int retries = 0;       // solver_retry events
  double max_speed = 0;  // fastest node over the run, mm/s
  bool stopped = false;  // a SimulationError stopped the run
  std::string message;   // its message
  bool always_finite = true;
};

// Steps `steps` times with input(step); checks the state after every step (and after a stop).
template <typename InputFn>
Outcome Drive(const Model& m, State* s, int steps, InputFn input) {
  Workspace ws;
  BuildWorkspace(m, *s, &ws);
  Outcome o;
  for (int k = 0; k < steps; ++k) {
    try {
      Step(m, input(s->step + 1), s, &ws);
    } catch (const SimulationError& e) {
      o.stopped = true;
      o.message = e.what();
      o.always_finite = o.always_finite && CheckSolve(*s).finite;
      return o;
    }
    const SolveHealth h = CheckSolve(*s);
    o.always_finite = o.always_finite && h.finite;
    o.max_speed = std::max(o.max_speed, h.max_speed_mm_s);
    for (const Event& e : s->events) o.retries += e.kind == "solver_retry" ? 1 : 0;
    ++o.steps;
  }
  return o;
}

TEST(SolveGuard, CheckSolveFindsTheFastestAndTheFirstNonFiniteNode) {
  const Model m = SmallModel();
  State s = MakeInitialState(m);
  s.soft_bodies[0].v.col(5) = Vec3(0, 300, 400);  // 500 mm/s
  s.threads[0].v.col(3) = Vec3(0, 0, -100);
  SolveHealth h = CheckSolve(s);
  EXPECT_TRUE(h.finite);
  EXPECT_DOUBLE_EQ(h.max_speed_mm_s, 500);
  EXPECT_EQ(h.body, 0);
  EXPECT_EQ(h.node, 5);
  EXPECT_FALSE(h.Diverged(m));  // 500 mm/s < 10 m/s
  s.threads[0].x(1, 7) = std::numeric_limits<double>::quiet_NaN();
  h = CheckSolve(s);
  EXPECT_FALSE(h.finite);
  EXPECT_TRUE(h.Diverged(m));
  EXPECT_EQ(h.kind, ConstraintEnd::Kind::kThread);
  EXPECT_EQ(h.node, 7);
  EXPECT_EQ(DescribeWorstNode(m, h), "thread 'suture' node 7 not finite");
  s.threads[0].node_alive[7] = 0;  // a node cut away is no longer checked
  EXPECT_TRUE(CheckSolve(s).finite);
}

TEST(SolveGuard, RestorePutsBackWhatTheSolvesWrite) {
  const Model m = SmallModel();
  State s = MakeInitialState(m);
  SolveStart start;
  SaveSolveStart(s, &start);
  const State before = s;
  s.soft_bodies[0].x.array() += 3;
  s.soft_bodies[0].v.array() = std::numeric_limits<double>::infinity();
  s.soft_bodies[0].dv_warm.array() = 1;
  s.threads[0].x.array() -= 2;
  s.threads[0].v.array() = 7;
  RestoreSolveStart(start, &s);
  EXPECT_TRUE(BitwiseEqual(s, before));
}

void Report(const char* what, const Outcome& o) {
  std::printf("%s: %d steps, %d retries, max node speed %.4g mm/s, stopped %d%s%s\n", what, o.steps,
              o.retries, o.max_speed, o.stopped ? 1 : 0, o.stopped ? ": " : "", o.message.c_str());
}

// Sound: every state finite, and either no node beyond the divergence speed or a stop.
void ExpectSound(const Model& m, const Outcome& o) {
  EXPECT_TRUE(o.always_finite);
  if (!o.stopped) {
    EXPECT_LE(o.max_speed, m.solver.divergence_speed_mm_s);
  }
}

TEST(SolveGuard, ToolTeleportingOneHundredMillimetresPerStepThroughTheBlock) {
  const Model m = SmallModel();
  State s = MakeInitialState(m);
  const Outcome o = Drive(
      m, &s, 60, [&](std::int64_t k) { return GrasperAt(m, Vec3(k % 2 ? -40.0 : 60.0, 10, 5)); });
  Report("teleport", o);
  ExpectSound(m, o);
  EXPECT_FALSE(o.stopped);
}

TEST(SolveGuard, ModulusOfOnePascalAndOneGigapascal) {
  for (double e_pa : {1.0, 1e9}) {
    Model m = SmallModel();
    for (Material& mat : m.materials) mat.young_modulus_pa = e_pa;
    for (SoftBodyModel& b : m.soft_bodies) b.material.young_modulus_pa = e_pa;
    State s = MakeInitialState(m);
    const Outcome o = Drive(m, &s, 150, [&](std::int64_t k) {
      return GrasperAt(m, Vec3(40.0 - 0.5 * static_cast<double>(k), 10, 12));
    });
    Report(e_pa < 2 ? "E = 1 Pa" : "E = 1 GPa", o);
    ExpectSound(m, o);
  }
}

TEST(SolveGuard, StepOfOneTenthOfASecond) {
  Model m = SmallModel();
  m.options.dt_s = 0.1;
  State s = MakeInitialState(m);
  const Outcome o = Drive(m, &s, 40, [&](std::int64_t k) {
    return GrasperAt(m, Vec3(40.0 - 3.0 * static_cast<double>(k), 10, 12));
  });
  Report("dt = 0.1 s", o);
  ExpectSound(m, o);
}

TEST(SolveGuard, ThreadPulledAtOneKilonewton) {
  const Model m = SmallModel();
  State s = MakeInitialState(m);
  SpringConstraint pull;
  pull.tag = "pull";
  pull.a.kind = ConstraintEnd::Kind::kThread;
  pull.a.index = 0;
  pull.a.nodes = {10, -1, -1, -1};
  pull.a.weights = {1, 0, 0, 0};
  pull.b.kind = ConstraintEnd::Kind::kWorld;
  pull.b.offset_mm = s.threads[0].x.col(10) + Vec3(1000, 0, 0);
  pull.stiffness_n_per_mm = 1.0;  // 1 000 N at the start
  physics::AddConstraint(&s, pull);
  const double x0 = s.threads[0].x(0, 10);
  const Outcome o = Drive(m, &s, 100, [&](std::int64_t) { return GrasperAt(m, Vec3(60, 10, 5)); });
  Report("thread at 1 kN", o);
  std::printf("thread end moved %.3f mm along the pull\n", s.threads[0].x(0, 10) - x0);
  ExpectSound(m, o);
  // The pull acts and the thread holds: stretched to its strain limit (20 mm at 1 %), no more.
  EXPECT_NEAR(s.threads[0].x(0, 10) - x0, m.thread_solver.max_strain * 20.0, 0.02);
}

// A free block spinning at 400 rad/s about z (8 rad per 20 ms step), no gravity: the
// linearised step keeps 99 % of the speed (5 601 of 5 657 mm/s at the fastest node), two
// half steps 45 % (2 562 mm/s), so with solver.divergence_speed at 4 000 mm/s the full step
// counts as diverged and its retry in two substeps as sound.
Model SpinningModel(double divergence_speed_mm_s, int max_substeps) {
  Model m = SmallModel();
  m.soft_bodies[0].fixed_nodes.clear();
  m.options.gravity_mm_s2 = Vec3::Zero();
  m.solver.divergence_speed_mm_s = divergence_speed_mm_s;
  m.solver.divergence_max_substeps = max_substeps;
  return m;
}

State Spinning(const Model& m, double omega_rad_s) {
  State s = MakeInitialState(m);
  SoftBodyState& b = s.soft_bodies[0];
  const Vec3 c = b.x.rowwise().mean();
  for (Eigen::Index n = 0; n < b.x.cols(); ++n)
    b.v.col(n) = Vec3(0, 0, omega_rad_s).cross(Vec3(b.x.col(n)) - c);
  return s;
}

InputFrame NoTools(const Model& m) {
  InputFrame f;
  f.camera.pose = m.camera.initial_pose;
  return f;
}

// Steps *s once from a fresh workspace: the SimulationError's message, "" if the step went
// through (then the test fails), after checking that the error names step 1.
std::string FirstStepStop(const Model& m, State* s) {
  Workspace ws;
  BuildWorkspace(m, *s, &ws);
  try {
    Step(m, NoTools(m), s, &ws);
  } catch (const SimulationError& e) {
    EXPECT_EQ(e.step(), 1);
    return e.what();
  }
  ADD_FAILURE() << "no SimulationError";
  return "";
}

TEST(SolveGuard, DivergedStepIsRedoneInSubstepsAndSaysSo) {
  const Model m = SpinningModel(4000, 16);
  State s = Spinning(m, 400);
  Workspace ws;
  BuildWorkspace(m, s, &ws);
  Step(m, NoTools(m), &s, &ws);
  EXPECT_EQ(s.step, 1);
  EXPECT_DOUBLE_EQ(s.time_s, m.options.dt_s);
  EXPECT_EQ(ws.timings.substeps, 2);
  const SolveHealth h = CheckSolve(s);
  EXPECT_TRUE(h.finite);
  EXPECT_LT(h.max_speed_mm_s, 4000);
  int retries = 0;
  for (const Event& e : s.events) {
    if (e.kind != "solver_retry") continue;
    ++retries;
    EXPECT_EQ(e.body, "block");
    EXPECT_EQ(e.step, 1);
    EXPECT_NE(e.detail.find("substeps=2 "), std::string::npos) << e.detail;
  }
  EXPECT_EQ(retries, 1);

  // The same as two steps of dt/2 (up to the CG tolerance: their preconditioner is the factor
  // of dt/2, the retry's that of dt).
  Model half = m;
  half.options.dt_s = m.options.dt_s / 2;
  half.solver.divergence_speed_mm_s = 1e5;
  State r = Spinning(half, 400);
  Workspace wr;
  BuildWorkspace(half, r, &wr);
  Step(half, NoTools(half), &r, &wr);
  Step(half, NoTools(half), &r, &wr);
  EXPECT_LT((s.soft_bodies[0].x - r.soft_bodies[0].x).cwiseAbs().maxCoeff(), 1e-6);
  EXPECT_LT((s.soft_bodies[0].v - r.soft_bodies[0].v).cwiseAbs().maxCoeff(), 1e-4);

  // Without the retry (one substep allowed) the same step stops the run.
  const Model no_retry = SpinningModel(4000, 1);
  State t = Spinning(no_retry, 400);
  Workspace wt;
  BuildWorkspace(no_retry, t, &wt);
  EXPECT_THROW(Step(no_retry, NoTools(no_retry), &t, &wt), SimulationError);
}

TEST(SolveGuard, StepThatDivergesEvenInSubstepsStopsWithTheStateOfItsStart) {
  const Model m = SpinningModel(100, 8);  // nothing spinning at 400 rad/s slows below 100 mm/s
  State s = Spinning(m, 400);
  const State start = s;
  const std::string what = FirstStepStop(m, &s);
  EXPECT_NE(what.find("step 1 "), std::string::npos) << what;
  EXPECT_NE(what.find("soft body 'block' node "), std::string::npos) << what;
  EXPECT_NE(what.find("even in 8 substeps"), std::string::npos) << what;
  EXPECT_TRUE(s.soft_bodies[0].x == start.soft_bodies[0].x);
  EXPECT_TRUE(s.soft_bodies[0].v == start.soft_bodies[0].v);
  EXPECT_TRUE(s.threads[0].x == start.threads[0].x);
  int retries = 0;
  for (const Event& e : s.events) retries += e.kind == "solver_retry" ? 1 : 0;
  EXPECT_EQ(retries, 3);  // 2, 4, 8
}

TEST(SolveGuard, NonFiniteStateStopsTheRunInsteadOfBeingWritten) {
  const Model m = SmallModel();
  State s = MakeInitialState(m);
  s.soft_bodies[0].v(0, 7) = std::numeric_limits<double>::quiet_NaN();  // a free node
  const std::string what = FirstStepStop(m, &s);
  EXPECT_NE(what.find("not finite"), std::string::npos) << what;
}

}  // namespace
}  // namespace arthrosim::sim
