// System-level verification of the soft-tissue solver: cantilever beam against an independent
// reference and beam theory, patch test, dynamics, topology changes, ARKODE, determinism.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "arthrosim/core/parallel.h"
#include "arthrosim/core/units.h"
#include "arthrosim/mesh/mesh_io.h"
#include "arthrosim/physics/fem_bench.h"
#include "arthrosim/physics/polar_decomposition.h"
#include "arthrosim/physics/soft_system.h"

namespace arthrosim::physics {
namespace {

std::string BeamPath(const char* h) {
  return std::string(ARTHROSIM_SOURCE_DIR) + "/tests/testdata/beam/beam_" + h + ".msh";
}

double StaticTip(const std::string& path) {
  const Model model = MakeBeamModel(mesh::ReadTetMesh(path), 0, 0);
  State state = MakeInitialState(model);
  SoftSystem sys;
  sys.Build(model, state);
  sys.SolveStatic(model, &state, 1);
  return BeamTipDeflection(state);
}

// Independent reference (linear tets on the same gmsh meshes): 0.7248 / 1.2335 / 1.4008 mm.
TEST(BeamStatic, MatchesReferenceAndConvergesToBeamTheory) {
  const double ref[3] = {0.7248, 1.2335, 1.4008};
  const char* h[3] = {"5", "2.5", "1.25"};
  double prev_err = 1e9;
  for (int i = 0; i < 3; ++i) {
    const double tip = -StaticTip(BeamPath(h[i]));
    std::printf("beam h=%s: static mean tip deflection %.5f mm (reference %.4f)\n", h[i], tip,
                ref[i]);
    EXPECT_NEAR(tip, ref[i], 0.005 * ref[i]) << "mesh h = " << h[i];
    const double err = std::abs(tip - kBeamEulerBernoulliTipMm) / kBeamEulerBernoulliTipMm;
    EXPECT_LT(err, prev_err) << "error to beam theory must shrink with refinement";
    prev_err = err;
  }
  EXPECT_LT(prev_err, 0.06);
}

// The damped dynamic solver settles onto the static solution (3 573 tets, dt 20 ms).
TEST(BeamDynamic, SettlesToStaticSolution) {
  for (SystemProduct product : {SystemProduct::kAssembled, SystemProduct::kMatrixFree}) {
    BeamBenchOptions opt;
    opt.mesh_path = BeamPath("2.5");
    opt.product = product;
    const BeamBenchResult r = RunBeamBenchmark(opt);
    std::printf(
        "%s: %d nodes %d tets, %.3f ms/step (rot %.3f asm %.3f solve %.3f), CG %.1f it "
        "(max %d), res %.2e, static %.5f settled %.5f err %.4f %%\n",
        product == SystemProduct::kAssembled ? "assembled" : "matrix-free", r.nodes, r.tets,
        r.ms_per_step, r.rotations_ms, r.assembly_ms, r.solve_ms, r.mean_cg_iterations,
        r.max_cg_iterations, r.mean_cg_residual, r.static_tip_mm, r.settled_tip_mm,
        r.beam_settled_error_pct);
    EXPECT_LT(r.beam_settled_error_pct, 0.5);
  }
}

Model CoarseBeam(double alpha, double beta) {
  return MakeBeamModel(mesh::ReadTetMesh(BeamPath("5")), alpha, beta);
}

bool OnBoundary(const Vec3& p) {
  const double e = 1e-9;
  return p.x() < e || p.x() > 100 - e || p.y() < e || p.y() > 10 - e || p.z() < e || p.z() > 10 - e;
}

// Patch test: an affine displacement gives one strain everywhere and no interior residual.
TEST(SoftSystem, PatchTestAffineDisplacement) {
  Model model = CoarseBeam(0, 0);
  model.soft_bodies[0].fixed_nodes.clear();
  State state = MakeInitialState(model);
  SoftSystem sys;
  sys.Build(model, state);
  Mat3 a;
  a << 1.004, 0.002, -0.001, 0.003, 0.997, 0.002, 0.001, -0.002, 1.003;
  SoftBodyState& b = state.soft_bodies[0];
  for (Eigen::Index i = 0; i < b.x.cols(); ++i) b.x.col(i) = a * b.x_rest.col(i) + Vec3(1, 2, 3);
  const Points f = sys.ElasticForces(model, state, 0);
  double boundary = 0, interior = 0;
  int n_interior = 0;
  for (Eigen::Index i = 0; i < f.cols(); ++i) {
    if (OnBoundary(b.x_rest.col(i))) {
      boundary = std::max(boundary, f.col(i).norm());
    } else {
      interior = std::max(interior, f.col(i).norm());
      ++n_interior;
    }
  }
  ASSERT_GT(n_interior, 0);
  ASSERT_GT(boundary, 0);
  EXPECT_LT(interior, 1e-10 * boundary);
  // Uniform strain: the energy is the energy density of eps = sym(R^T A) - I times the volume.
  const Mat3 r = PolarRotation(a);
  Mat3 eps = 0.5 * (r.transpose() * a + a.transpose() * r);
  eps.diagonal().array() -= 1.0;
  const Lame lame = LameFromMaterial(model.soft_bodies[0].material);
  const double density =
      lame.mu * eps.squaredNorm() + 0.5 * lame.lambda * eps.trace() * eps.trace();
  EXPECT_NEAR(sys.ComputeEnergies(model, state).elastic_uj, density * 10000.0,
              1e-9 * density * 10000.0);
}

// Rigid rotations (including 90 and 180 degrees) of an unstressed mesh give no elastic force.
TEST(SoftSystem, RigidRotationsGiveZeroForce) {
  Model model = CoarseBeam(0, 0);
  State state = MakeInitialState(model);
  SoftSystem sys;
  sys.Build(model, state);
  SoftBodyState& b = state.soft_bodies[0];
  const Points rest = b.x_rest;
  for (Eigen::Index i = 0; i < b.x.cols(); ++i) b.x(0, i) = 1.01 * rest(0, i);
  // Force scale per unit strain (forces are linear in a small stretch).
  const double scale = sys.ElasticForces(model, state, 0).colwise().norm().maxCoeff() / 0.01;
  ASSERT_GT(scale, 0);
  const Mat3 rotations[] = {
      Eigen::AngleAxisd(units::kPi / 2, Vec3::UnitZ()).toRotationMatrix(),
      Eigen::AngleAxisd(units::kPi, Vec3::UnitY()).toRotationMatrix(),
      Eigen::AngleAxisd(units::kPi, Vec3(1, 2, 3).normalized()).toRotationMatrix(),
      Eigen::AngleAxisd(-units::kPi / 2, Vec3(1, -1, 0).normalized()).toRotationMatrix(),
      Eigen::AngleAxisd(0.3, Vec3(0, 1, 1).normalized()).toRotationMatrix()};
  for (const Mat3& r : rotations) {
    for (Eigen::Index i = 0; i < b.x.cols(); ++i) b.x.col(i) = r * rest.col(i) + Vec3(5, -7, 9);
    const Points f = sys.ElasticForces(model, state, 0);
    EXPECT_LT(f.colwise().norm().maxCoeff(), 1e-12 * scale);
    EXPECT_LT(sys.ComputeEnergies(model, state).elastic_uj, 1e-12);
  }
}

// Free vibration from a bent shape without gravity: the damped energy never grows, and
// undamped implicit Euler loses energy at every step (its numerical dissipation).
TEST(SoftSystem, FreeVibrationEnergyDecays) {
  for (double damping : {0.5, 0.0}) {
    Model model = CoarseBeam(damping, damping * 0.01);
    model.solver.cg_tolerance = 1e-12;
    model.solver.cg_max_iterations = 500;
    model.options.dt_s = 0.002;
    State state = MakeInitialState(model);
    SoftSystem sys;
    sys.Build(model, state);
    sys.SolveStatic(model, &state, 1);  // bent by gravity
    model.options.gravity_mm_s2 = Vec3::Zero();
    double prev = sys.ComputeEnergies(model, state).total();
    ASSERT_GT(prev, 0);
    const double e0 = prev;
    for (int k = 0; k < 100; ++k) {
      sys.Step(model, nullptr, nullptr, &state);
      const double e = sys.ComputeEnergies(model, state).total();
      EXPECT_LE(e, prev * (1 + 1e-9)) << "step " << k << " damping " << damping;
      if (damping == 0) {
        EXPECT_LT(e, prev) << "step " << k;
      }
      prev = e;
    }
    EXPECT_LT(prev, 0.9 * e0);
  }
}

// Remove, split and re-rest: masses, volumes, and bit-identity with a rebuild from scratch.
TEST(SoftSystem, TopologyChangesKeepConsistentSystem) {
  Model model = CoarseBeam(1.0, 0.01);
  State state = MakeInitialState(model);
  SoftSystem sys;
  sys.Build(model, state);
  const double rho = 1000 * units::kKgPerM3ToInternal;
  EXPECT_NEAR(sys.TotalMass(), rho * 10000, 1e-9 * rho * 10000);
  for (int k = 0; k < 5; ++k) sys.Step(model, nullptr, nullptr, &state);
  // Cut: remove every tet with its centroid near x = 60.
  std::vector<std::int32_t> cut;
  const SoftBodyState& b = state.soft_bodies[0];
  for (std::size_t t = 0; t < b.tets.size(); ++t) {
    Vec3 c = Vec3::Zero();
    for (std::int32_t n : b.tets[t]) c += 0.25 * b.x_rest.col(n);
    if (std::abs(c.x() - 60) < 3 && c.z() > 5) cut.push_back(static_cast<std::int32_t>(t));
  }
  ASSERT_FALSE(cut.empty());
  sys.RemoveTets(0, cut, &state);
  // Split a few tets 1 -> 4 (enough to force a re-layout of the slot range too).
  for (int k = 0; k < 40; ++k) {
    std::int32_t t = 7 * k + 3;
    while (!state.soft_bodies[0].tet_alive[static_cast<std::size_t>(t)]) ++t;
    sys.SplitTet(model, 0, t, {0.1, 0.2, 0.3, 0.4}, &state);
  }
  // Plastic re-rest: shave 0.3 mm off the top near the tip.
  std::vector<std::int32_t> nodes;
  for (Eigen::Index i = 0; i < state.soft_bodies[0].x_rest.cols(); ++i) {
    const Vec3 p = state.soft_bodies[0].x_rest.col(i);
    if (p.x() > 80 && p.z() > 9.999) nodes.push_back(static_cast<std::int32_t>(i));
  }
  Points rest(3, static_cast<Eigen::Index>(nodes.size()));
  for (std::size_t i = 0; i < nodes.size(); ++i) {
    rest.col(static_cast<Eigen::Index>(i)) =
        state.soft_bodies[0].x_rest.col(nodes[i]) - Vec3(0, 0, 0.3);
  }
  sys.SetRestPositions(0, nodes, rest, &state);

  EXPECT_NEAR(sys.TotalMass(), rho * sys.AliveVolume(0), 1e-12 * sys.TotalMass());
  EXPECT_LT(sys.AliveVolume(0), 10000.0);
  // Nodes of removed tets only drop out of the solve.
  int dropped = 0;
  for (Eigen::Index i = 0; i < state.soft_bodies[0].x.cols(); ++i) {
    if (sys.NodeMass(0, static_cast<std::int32_t>(i)) == 0) {
      ++dropped;
      EXPECT_FALSE(sys.IsFree(0, static_cast<std::int32_t>(i)));
    }
  }
  // Incremental updates and a rebuild from the same State give the same bits.
  SoftSystem fresh;
  fresh.Build(model, state);
  EXPECT_EQ(fresh.TotalMass(), sys.TotalMass());
  State s1 = state, s2 = state;
  for (int k = 0; k < 3; ++k) {
    sys.Step(model, nullptr, nullptr, &s1);
    fresh.Step(model, nullptr, nullptr, &s2);
  }
  EXPECT_TRUE(BitwiseEqual(s1, s2));
  // Bounded and finite over 1 000 steps.
  double emax = 0;
  for (int k = 0; k < 1000; ++k) {
    sys.Step(model, nullptr, nullptr, &s1);
    emax = std::max(emax, std::abs(sys.ComputeEnergies(model, s1).total()));
  }
  EXPECT_TRUE(s1.soft_bodies[0].x.allFinite());
  EXPECT_TRUE(s1.soft_bodies[0].v.allFinite());
  EXPECT_LT(emax, 1e3);  // uJ; the beam's gravitational energy scale is ~ m g L ~ 5e2
  std::printf("topology: %zu cut, 40 split, %zu re-rested, %d nodes dropped, max |E| %.3g uJ\n",
              cut.size(), nodes.size(), dropped, emax);
}

// Two bodies joined at coincident nodes behave as one body.
TEST(SoftSystem, JoinedBodiesActAsOne) {
  const Model whole = CoarseBeam(0, 0);
  const mesh::TetMesh& m = whole.soft_bodies[0].rest_mesh;
  Model split = whole;
  split.soft_bodies.clear();
  for (int part = 0; part < 2; ++part) {
    SoftBodyModel body = whole.soft_bodies[0];
    body.name.assign(1, part == 0 ? 'a' : 'b');
    body.rest_mesh.tets.clear();
    for (const mesh::Tet& t : m.tets) {
      Vec3 c = Vec3::Zero();
      for (std::int32_t n : t) c += 0.25 * m.nodes.col(n);
      if ((c.x() < 50) == (part == 0)) body.rest_mesh.tets.push_back(t);
    }
    if (part == 1) body.fixed_nodes.clear();
    split.soft_bodies.push_back(body);
  }
  split.joins.push_back(Join{"a", "b", 1e-6});
  State s_whole = MakeInitialState(whole), s_split = MakeInitialState(split);
  SoftSystem a, b;
  a.Build(whole, s_whole);
  b.Build(split, s_split);
  EXPECT_NEAR(a.TotalMass(), b.TotalMass(), 1e-12 * a.TotalMass());
  a.SolveStatic(whole, &s_whole, 1);
  b.SolveStatic(split, &s_split, 1);
  const double tip = BeamTipDeflection(s_whole);
  State view = s_split;
  view.soft_bodies.erase(view.soft_bodies.begin());  // tip nodes live in body b
  EXPECT_NEAR(BeamTipDeflection(view), tip, 1e-9 * std::abs(tip));
  for (int k = 0; k < 3; ++k) b.Step(split, nullptr, nullptr, &s_split);
  int shared = 0;
  for (Eigen::Index i = 0; i < m.nodes.cols(); ++i) {
    const NodeRef own = b.Owner(1, static_cast<std::int32_t>(i));
    if (own.body != 0) continue;
    ++shared;
    EXPECT_EQ(s_split.soft_bodies[1].x.col(i), s_split.soft_bodies[0].x.col(own.node));
    EXPECT_EQ(s_split.soft_bodies[1].v.col(i), s_split.soft_bodies[0].v.col(own.node));
  }
  EXPECT_GT(shared, 10);
}

// A contact that is apart at the start of a step but crossed within it takes part in that step:
// a free block thrown at 150 mm/s (3 mm per 20 ms step) toward planes 0.5 mm below its bottom
// face stops at them in the step it reaches them, instead of ending that step 2.5 mm through
// and being pushed back only in the next one.
TEST(SoftSystem, ContactCrossedWithinAStepHoldsInThatStep) {
  Model model = CoarseBeam(0.0, 0.0);
  model.soft_bodies[0].fixed_nodes.clear();
  model.options.gravity_mm_s2 = Vec3::Zero();
  model.options.dt_s = 0.02;
  State state = MakeInitialState(model);
  SoftBodyState& b = state.soft_bodies[0];
  for (Eigen::Index i = 0; i < b.v.cols(); ++i) b.v.col(i) = Vec3(0, 0, -150);
  SoftSystem sys;
  sys.Build(model, state);
  ContactSet contacts;
  for (Eigen::Index i = 0; i < b.x.cols(); ++i) {
    if (b.x_rest(2, i) > 1e-6) continue;  // bottom face
    PointContact c;
    c.index = 0;
    c.nodes = {static_cast<std::int32_t>(i), -1, -1, -1};
    c.weights = {1, 0, 0, 0};
    c.normal = Vec3::UnitZ();
    c.offset_mm = -0.5;
    c.stiffness_n_per_mm = 20;
    contacts.push_back(c);
  }
  ASSERT_GT(contacts.size(), 10u);
  const SoftStepStats st = sys.Step(model, &contacts, nullptr, &state);
  EXPECT_GE(st.contact_resolves, 1);
  double deepest = 0, force = 0;
  for (const PointContact& c : contacts) {
    deepest = std::max(deepest, c.offset_mm - b.x(2, c.nodes[0]));
    force += c.force_n;
  }
  std::printf("deepest %.4f mm after the step that crossed the planes, force %.3f N\n", deepest,
              force);
  EXPECT_LT(deepest, 0.05);  // 2.5 mm if the planes only act from the next step
  EXPECT_GT(force, 0.0);
  // The block does not pass later either, and comes to rest on the planes.
  for (int k = 0; k < 20; ++k) sys.Step(model, &contacts, nullptr, &state);
  for (const PointContact& c : contacts) EXPECT_LT(c.offset_mm - b.x(2, c.nodes[0]), 0.05);
}

// A penalty contact and a spring enter the implicit system and report their forces.
TEST(SoftSystem, ContactAndSpringForces) {
  Model model = CoarseBeam(2.0, 0.01);
  State state = MakeInitialState(model);
  SoftSystem sys;
  sys.Build(model, state);
  // Support every tip-face node from below at z >= -0.3 mm (free tip sags 0.72 mm).
  ContactSet contacts;
  const SoftBodyState& b = state.soft_bodies[0];
  for (Eigen::Index i = 0; i < b.x.cols(); ++i) {
    if (b.x_rest(0, i) < 100 - 1e-6) continue;
    PointContact c;
    c.index = 0;
    c.nodes = {static_cast<std::int32_t>(i), -1, -1, -1};
    c.weights = {1, 0, 0, 0};
    c.normal = Vec3::UnitZ();
    c.offset_mm = b.x_rest(2, i) - 0.3;
    c.stiffness_n_per_mm = 50;
    contacts.push_back(c);
  }
  for (int k = 0; k < 150; ++k) sys.Step(model, &contacts, nullptr, &state);
  double total_n = 0;
  for (const PointContact& c : contacts) total_n += c.force_n;
  const double tip = BeamTipDeflection(state);
  EXPECT_LT(tip, -0.29);
  EXPECT_GT(tip, -0.32);
  // The support carries part of the weight (beam weight 0.0981 N).
  EXPECT_GT(total_n, 0.01);
  EXPECT_LT(total_n, 0.0981);
  // A spring lifting the tip centre node to 2 mm above its rest position.
  SpringSet springs(1);
  PointSpring& sp = springs[0];
  sp.index = 0;
  std::int32_t node = -1;
  for (Eigen::Index i = 0; i < b.x.cols(); ++i) {
    if (b.x_rest(0, i) > 100 - 1e-6 &&
        (node < 0 || (b.x_rest.col(i) - Vec3(100, 5, 5)).norm() <
                         (b.x_rest.col(node) - Vec3(100, 5, 5)).norm()))
      node = static_cast<std::int32_t>(i);
  }
  sp.nodes = {node, -1, -1, -1};
  sp.weights = {1, 0, 0, 0};
  sp.anchor_mm = b.x_rest.col(node) + Vec3(0, 0, 2);
  sp.stiffness_n_per_mm = 0.5;
  for (int k = 0; k < 150; ++k) sys.Step(model, nullptr, &springs, &state);
  const Vec3 d = state.soft_bodies[0].x.col(node) - sp.anchor_mm;
  EXPECT_NEAR((sp.force_n + sp.stiffness_n_per_mm * d).norm(), 0, 1e-12);
  EXPECT_GT(sp.force_n.z(), 0.05);  // lifts more than the beam weight's share
  EXPECT_GT(state.soft_bodies[0].x(2, node) - b.x_rest(2, node), 0.0);
}

// ARKODE (backward Euler DIRK, one Newton step, CG inside) agrees with the built-in step.
TEST(SoftSystem, ArkodeMatchesImplicitEuler) {
  Model model = CoarseBeam(1.0, 0.001);
  model.options.dt_s = 0.001;
  model.solver.cg_tolerance = 1e-10;
  model.solver.cg_max_iterations = 200;
  State s_ie = MakeInitialState(model), s_ark = s_ie;
  SoftSystem a, b;
  a.Build(model, s_ie);
  b.Build(model, s_ark);
  Model model_ark = model;
  model_ark.solver.integrator = Integrator::kArkode;
  double max_tip = 0, max_diff = 0;
  for (int k = 0; k < 60; ++k) {
    a.Step(model, nullptr, nullptr, &s_ie);
    const SoftStepStats st = b.Step(model_ark, nullptr, nullptr, &s_ark);
    EXPECT_GT(st.cg_iterations, 0);
    s_ie.time_s += model.options.dt_s;
    s_ark.time_s += model.options.dt_s;
    max_tip = std::max(max_tip, std::abs(BeamTipDeflection(s_ie)));
    max_diff = std::max(max_diff, std::abs(BeamTipDeflection(s_ie) - BeamTipDeflection(s_ark)));
  }
  ASSERT_GT(max_tip, 0.05);
  EXPECT_LT(max_diff, 0.01 * max_tip);
  std::printf("ARKODE vs implicit Euler: max tip %.4f mm, max difference %.3g mm\n", max_tip,
              max_diff);
  // Same static equilibrium: settle with ARKODE at dt 20 ms and heavy damping.
  Model settle = CoarseBeam(0.1, 0.1);
  settle.solver.integrator = Integrator::kArkode;
  State s = MakeInitialState(settle);
  SoftSystem c;
  c.Build(settle, s);
  for (int k = 0; k < 100; ++k) c.Step(settle, nullptr, nullptr, &s);
  const double static_tip = StaticTip(BeamPath("5"));
  EXPECT_NEAR(BeamTipDeflection(s), static_tip, 0.005 * std::abs(static_tip));
}

// Threads 1 and 2 give bit-identical states.
TEST(SoftSystem, ThreadCountDoesNotChangeBits) {
  const Model model = MakeBeamModel(mesh::ReadTetMesh(BeamPath("2.5")), 0.1, 0.01);
  State s1 = MakeInitialState(model), s2 = s1;
  SoftSystem a, b;
  SetThreadCount(1);
  a.Build(model, s1);
  for (int k = 0; k < 5; ++k) a.Step(model, nullptr, nullptr, &s1);
  SetThreadCount(2);
  b.Build(model, s2);
  for (int k = 0; k < 5; ++k) b.Step(model, nullptr, nullptr, &s2);
  SetThreadCount(1);
  EXPECT_TRUE(BitwiseEqual(s1, s2));
  EXPECT_NE(s1.soft_bodies[0].x, s1.soft_bodies[0].x_rest);
}

bool Same(const Points& a, const Points& b) {
  return a.rows() == b.rows() && a.cols() == b.cols() && (a.array() == b.array()).all();
}

// One step as the sim layer takes it (SoftSystem::Step leaves the step index to its caller).
SoftStepStats StepOnce(SoftSystem* sys, const Model& model, State* s) {
  const SoftStepStats st = sys->Step(model, nullptr, nullptr, s);
  ++s->step;
  return st;
}

// The factor's source lives in State: a system built afresh from a copied State (a restore)
// continues bit for bit, also while a requested factor is being prepared (the copy is taken
// inside the lag window) and when the anchor keeps moving (a request after every step with more
// than 1 CG iteration).
TEST(SoftSystem, RestoreWithMovingFactorAnchorIsBitIdentical) {
  Model model = CoarseBeam(0.1, 0.01);
  model.solver.refactor_iterations = 1;
  model.solver.refactor_lag_steps = 4;
  State s = MakeInitialState(model);
  SoftSystem a;
  a.Build(model, s);
  int moved = 0, switched = 0;
  for (int k = 0; k < 40 && !(switched > 0 && s.factor_switch_step > s.step + 1); ++k) {
    const SoftStepStats st = StepOnce(&a, model, &s);
    moved += st.anchor_moved ? 1 : 0;
    switched += st.refactored && k > 0 ? 1 : 0;
  }
  ASSERT_GT(moved, 1);
  ASSERT_GT(switched, 0);
  ASSERT_GT(s.soft_bodies[0].x_factor.cols(), 0);
  ASSERT_GT(s.factor_switch_step, s.step + 1);  // the copy is taken inside a lag window
  State restored = s;
  SoftSystem b;
  b.Build(model, restored);
  for (int k = 0; k < 10; ++k) {
    StepOnce(&a, model, &s);
    StepOnce(&b, model, &restored);
  }
  EXPECT_TRUE(BitwiseEqual(s, restored));
}

// Deferred refactorisation: the step that needs more than refactor_iterations CG iterations
// (step R) requests a factor of its end positions; steps R + 1 ... R + lag - 1 prepare it in
// parts and still use the old one; step R + lag uses it. The same holds whatever the part
// timing, and CG meets its tolerance at every step.
TEST(SoftSystem, RequestedFactorIsUsedExactlyLagStepsLater) {
  Model model = CoarseBeam(0.1, 0.01);
  model.solver.refactor_iterations = 1;
  for (int lag : {1, 2, 5}) {
    model.solver.refactor_lag_steps = lag;
    State s = MakeInitialState(model);
    SoftSystem sys;
    sys.Build(model, s);
    StepOnce(&sys, model, &s);  // builds the first factor at once
    std::int64_t request = -1;
    Points requested;
    for (int k = 0; k < 30 && request < 0; ++k) {
      const std::int64_t at = s.step;
      if (StepOnce(&sys, model, &s).anchor_moved) {
        request = at;
        requested = s.soft_bodies[0].x;
      }
    }
    ASSERT_GE(request, 0) << lag;
    EXPECT_EQ(s.factor_switch_step, request + lag) << lag;
    EXPECT_TRUE(Same(s.soft_bodies[0].x_factor_next, requested)) << lag;
    for (int j = 1; j < lag; ++j) {
      const SoftStepStats st = StepOnce(&sys, model, &s);
      EXPECT_FALSE(st.refactored) << lag << " " << j;
      EXPECT_TRUE(st.factor_work) << lag << " " << j;
      EXPECT_LE(st.cg_relative_residual, model.solver.cg_tolerance);
      EXPECT_FALSE(Same(s.soft_bodies[0].x_factor, requested)) << lag << " " << j;
    }
    ASSERT_EQ(s.step, request + lag);
    const SoftStepStats st = StepOnce(&sys, model, &s);
    EXPECT_TRUE(st.refactored) << lag;
    EXPECT_LE(st.cg_relative_residual, model.solver.cg_tolerance);
    EXPECT_TRUE(Same(s.soft_bodies[0].x_factor, requested)) << lag;
    EXPECT_EQ(s.factor_switch_step == -1 || s.factor_switch_step > request + lag, true) << lag;
  }
}

// Adaptive trigger (SolverOptions::refactor_slack_iterations): the first solve with a new factor
// sets State::factor_baseline_cg, and a step asks for a factor only when its CG needs more than
// refactor_iterations and more than that baseline plus the slack. Slack 0 keeps the plain rule
// (every step above refactor_iterations asks); a slack the drift cannot exceed asks never.
TEST(SoftSystem, SlackAsksForAFactorOnlyBeyondTheFirstSolveOfTheOneInUse) {
  auto run = [](int slack, int* asked, int* above_threshold) {
    Model model = CoarseBeam(0.1, 0.01);
    model.solver.refactor_iterations = 1;
    model.solver.refactor_slack_iterations = slack;
    State s = MakeInitialState(model);
    SoftSystem sys;
    sys.Build(model, s);
    *asked = *above_threshold = 0;
    for (int k = 0; k < 40; ++k) {
      const bool pending = s.factor_switch_step >= 0;
      const std::int32_t baseline = s.factor_baseline_cg;
      const SoftStepStats st = StepOnce(&sys, model, &s);
      if (st.refactored) {
        EXPECT_EQ(s.factor_baseline_cg, st.cg_iterations) << slack << " " << k;
        continue;  // its baseline is itself
      }
      EXPECT_EQ(s.factor_baseline_cg, baseline) << slack << " " << k;
      if (pending) continue;
      const bool above = st.cg_iterations > model.solver.refactor_iterations;
      *above_threshold += above ? 1 : 0;
      const bool expected = above && (slack == 0 || st.cg_iterations > baseline + slack);
      EXPECT_EQ(st.anchor_moved, expected)
          << slack << " " << k << " cg " << st.cg_iterations << " baseline " << baseline;
      *asked += st.anchor_moved ? 1 : 0;
    }
  };
  int asked0 = 0, above0 = 0;
  run(0, &asked0, &above0);
  EXPECT_GE(asked0, 3);
  EXPECT_EQ(asked0, above0);
  int asked2 = 0, above2 = 0;
  run(2, &asked2, &above2);
  EXPECT_GT(asked2, 0);       // the factor drifts past the slack now and then
  EXPECT_LT(asked2, above2);  // but not every step above the threshold asks
  int asked_never = 0, above_never = 0;
  run(1000, &asked_never, &above_never);
  EXPECT_EQ(asked_never, 0);
  EXPECT_GE(above_never, 10);  // the drift it ignores
  std::printf(
      "asked for a factor in 40 steps: slack 0: %d, slack 2: %d of %d above the threshold, "
      "slack 1000: 0 of %d\n",
      asked0, asked2, above2, above_never);
}

// The baseline is part of the factor's state: a system built afresh from a copied State (a
// restore, which factors the source in use again) keeps it and asks at the same steps. Every
// state of a run, restored into a fresh system and stepped once, gives the run's next state.
TEST(SoftSystem, SlackTriggerRestoresBitForBit) {
  Model model = CoarseBeam(0.1, 0.01);
  model.solver.refactor_iterations = 1;
  model.solver.refactor_slack_iterations = 2;
  std::vector<State> run = {MakeInitialState(model)};
  SoftSystem a;
  a.Build(model, run.back());
  for (int k = 0; k < 30; ++k) {
    run.push_back(run.back());
    StepOnce(&a, model, &run.back());
  }
  for (std::size_t k = 1; k + 1 < run.size(); ++k) {
    State restored = run[k];
    SoftSystem b;
    b.Build(model, restored);
    StepOnce(&b, model, &restored);
    EXPECT_TRUE(BitwiseEqual(restored, run[k + 1])) << k;
  }
}

// Topology edits while a factor is in use: the factor keeps its mesh (recorded in State before
// the edit) and removed nodes drop out of it. A system rebuilt from the State (a restore) gives
// the same bits, and CG meets its tolerance. (Split nodes make the next step factor its mesh at
// once: the ThreadCount/Topology tests cover that path.)
TEST(SoftSystem, FactorOfAnOlderMeshRestoresBitForBit) {
  Model model = CoarseBeam(0.1, 0.01);
  model.solver.refactor_lag_steps = 3;
  State s = MakeInitialState(model);
  SoftSystem a;
  a.Build(model, s);
  for (int k = 0; k < 3; ++k) StepOnce(&a, model, &s);
  std::vector<std::int32_t> cut;
  const SoftBodyState& b = s.soft_bodies[0];
  for (std::size_t t = 0; t < b.tets.size(); ++t) {
    Vec3 c = Vec3::Zero();
    for (std::int32_t n : b.tets[t]) c += 0.25 * b.x_rest.col(n);
    if (std::abs(c.x() - 60) < 3 && c.z() > 5) cut.push_back(static_cast<std::int32_t>(t));
  }
  a.RemoveTets(0, cut, &s);
  // The factor keeps the mesh before the cut (recorded in State by the edit).
  ASSERT_EQ(s.soft_bodies[0].factor_alive.size(), b.tets.size());
  EXPECT_NE(s.soft_bodies[0].factor_alive, s.soft_bodies[0].tet_alive);
  State restored = s;
  SoftSystem fresh;
  fresh.Build(model, restored);
  for (int k = 0; k < 12; ++k) {
    const SoftStepStats st = StepOnce(&a, model, &s);
    StepOnce(&fresh, model, &restored);
    EXPECT_LE(st.cg_relative_residual, model.solver.cg_tolerance) << k;
  }
  EXPECT_TRUE(BitwiseEqual(s, restored));
}

// The solver settings come from the Model (SolverOptions): Build takes them, and they act. The
// warped factor needs few CG iterations; block Jacobi on the same steps needs many more.
TEST(SoftSystem, BuildTakesTheSolverSettingsOfTheModel) {
  Model model = CoarseBeam(0.1, 0.01);
  const State start = MakeInitialState(model);
  auto iterations = [&](const Model& m) {
    State s = start;
    SoftSystem sys;
    sys.Build(m, s);
    int total = 0;
    for (int k = 0; k < 5; ++k) total += sys.Step(m, nullptr, nullptr, &s).cg_iterations;
    return total;
  };
  SoftSystem defaults;
  State s = start;
  defaults.Build(model, s);
  EXPECT_EQ(defaults.preconditioner(), Preconditioner::kRestCholesky);
  EXPECT_EQ(defaults.product(), SystemProduct::kAssembled);
  EXPECT_EQ(defaults.refactor_iterations(), 10);
  const int factored = iterations(model);
  model.solver.preconditioner = Preconditioner::kBlockJacobi;
  model.solver.product = SystemProduct::kMatrixFree;
  model.solver.refactor_iterations = 3;
  SoftSystem changed;
  s = start;
  changed.Build(model, s);
  EXPECT_EQ(changed.preconditioner(), Preconditioner::kBlockJacobi);
  EXPECT_EQ(changed.product(), SystemProduct::kMatrixFree);
  EXPECT_EQ(changed.refactor_iterations(), 3);
  const int jacobi = iterations(model);
  std::printf("CG iterations over 5 steps: rest_cholesky %d, block_jacobi %d\n", factored, jacobi);
  EXPECT_GT(jacobi, 2 * factored);
}

}  // namespace
}  // namespace arthrosim::physics
