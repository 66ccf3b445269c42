// SoftSystem step stages, the built-in linearised implicit Euler step, and the stages an
// external integrator (ARKODE) drives.
#include "arthrosim/physics/soft_system.h"

#include <Eigen/Sparse>
#include <algorithm>
#include <cmath>
#include <functional>
#include <string>
#include <utility>

#include "arthrosim/core/error.h"
#include "arthrosim/core/parallel.h"
#include "arthrosim/core/units.h"
#include "arthrosim/physics/arkode_integrator.h"
#include "arthrosim/physics/cg_solver.h"
#include "arthrosim/physics/polar_decomposition.h"
#include "soft_internal.h"

namespace arthrosim::physics {
using namespace soft_internal;  // NOLINT: this file is part of SoftSystem

// ------------------------------------------------------------------------------------------
// Step stages

void SoftSystem::Gather(const State& state) {
  x_.setZero();
  v_.setZero();
  dv_.setZero();
  for (std::int32_t s = 0; s < slots_; ++s) {
    const NodeRef r = slot_node_[static_cast<std::size_t>(s)];
    if (r.body < 0) continue;
    const SoftBodyState& sb = state.soft_bodies[static_cast<std::size_t>(r.body)];
    Seg(x_, s) = sb.x.col(r.node);
    if (free_[static_cast<std::size_t>(s)]) {
      Seg(v_, s) = sb.v.col(r.node);
      Seg(dv_, s) = sb.dv_warm.col(r.node);
    }
  }
}

void SoftSystem::ComputeRotationsAndForces(const Eigen::VectorXd& x) {
  for (Body& bd : bodies_) {
    const auto nt = static_cast<std::int64_t>(bd.rest.size());
    ParallelFor(nt, kTetBlock, [&](std::int64_t begin, std::int64_t end) {
      // Batches of live tets: deformation gradients, their rotations side by side, then forces.
      constexpr int kBatch = 32;
      std::array<Mat3, kBatch> fs, rs;
      std::array<std::size_t, kBatch> ids;
      std::int64_t t = begin;
      while (t < end) {
        int m = 0;
        for (; t < end && m < kBatch; ++t) {
          const auto ti = static_cast<std::size_t>(t);
          const TetRest& rest = bd.rest[ti];
          if (!bd.alive[ti] || rest.degenerate) continue;
          const auto& s = bd.tet_slot[ti];
          fs[static_cast<std::size_t>(m)] =
              DeformationGradient(rest, Seg(x, s[0]), Seg(x, s[1]), Seg(x, s[2]), Seg(x, s[3]));
          ids[static_cast<std::size_t>(m++)] = ti;
        }
        PolarRotations(fs.data(), rs.data(), m);
        for (int k = 0; k < m; ++k) {
          const std::size_t ti = ids[static_cast<std::size_t>(k)];
          bd.rotation[ti] = rs[static_cast<std::size_t>(k)];
          ElementForces(bd.rest[ti], bd.rotation[ti], fs[static_cast<std::size_t>(k)], bd.lame,
                        &bd.force[ti]);
        }
      }
    });
  }
  f_.setZero();
  for (const Body& bd : bodies_) {
    for (std::size_t t = 0; t < bd.rest.size(); ++t) {
      if (!bd.alive[t] || bd.rest[t].degenerate) continue;
      for (int a = 0; a < 4; ++a)
        Seg(f_, bd.tet_slot[t][static_cast<std::size_t>(a)]) +=
            bd.force[t][static_cast<std::size_t>(a)];
    }
  }
}

void SoftSystem::AddGravity(const Model& model) {
  const Vec3 g = model.options.gravity_mm_s2;
  for (std::int32_t s = 0; s < slots_; ++s) {
    if (free_[static_cast<std::size_t>(s)]) Seg(f_, s) += mass_[static_cast<std::size_t>(s)] * g;
  }
}

void SoftSystem::AssembleStiffness(double scale_h, double h, bool assembled) {
  // Per body the stiffness scale is h (h + beta) in a step, 1 in a static solve (scale_h = 0).
  h_ = h;
  kscales_.resize(bodies_.size());
  kmat_.SetZero();
  for (std::size_t b = 0; b < bodies_.size(); ++b) {
    const Body& bd = bodies_[b];
    const double scale = scale_h > 0 ? scale_h * (scale_h + bd.beta) : 1.0;
    kscales_[b] = scale;
    std::array<Mat3, 10> blocks;
    for (std::size_t t = 0; t < bd.rest.size(); ++t) {
      if (!bd.alive[t] || bd.rest[t].degenerate) continue;
      ElementStiffnessBlocks(bd.rest[t], bd.rotation[t], bd.lame, scale, &blocks);
      const auto& s = bd.tet_slot[t];
      for (int a = 0; a < 4; ++a)
        kmat_.diag(s[static_cast<std::size_t>(a)]) += blocks[static_cast<std::size_t>(a)];
      if (!assembled) continue;
      for (int e = 0; e < 6; ++e) {
        const std::int32_t idx = bd.tet_pair[t][static_cast<std::size_t>(e)];
        const std::int32_t si =
            s[static_cast<std::size_t>(kTetEdges[static_cast<std::size_t>(e)][0])];
        const std::int32_t sj =
            s[static_cast<std::size_t>(kTetEdges[static_cast<std::size_t>(e)][1])];
        if (si < sj) {
          kmat_.block(idx) += blocks[static_cast<std::size_t>(4 + e)];
        } else {
          kmat_.block(idx) += blocks[static_cast<std::size_t>(4 + e)].transpose();
        }
      }
    }
  }
}

void SoftSystem::BuildPointTerms(const Model& model, const Eigen::VectorXd& x, ContactSet* contacts,
                                 SpringSet* springs, bool add_forces) {
  terms_.clear();
  auto make = [&](PointContact::Target target, std::int32_t index,
                  const std::array<std::int32_t, 4>& nodes, const std::array<double, 4>& w,
                  PointTerm* term, Vec3* p) {
    if (target != PointContact::Target::kSoftBody || index < 0 ||
        static_cast<std::size_t>(index) >= bodies_.size()) {
      return false;
    }
    const Body& bd = bodies_[static_cast<std::size_t>(index)];
    *p = Vec3::Zero();
    bool any = false;
    for (int a = 0; a < 4; ++a) {
      const std::int32_t n = nodes[static_cast<std::size_t>(a)];
      if (n < 0 || static_cast<std::size_t>(n) >= bd.slot.size()) continue;
      term->slot[static_cast<std::size_t>(a)] = bd.slot[static_cast<std::size_t>(n)];
      term->w[static_cast<std::size_t>(a)] = w[static_cast<std::size_t>(a)];
      *p += w[static_cast<std::size_t>(a)] * Seg(x, term->slot[static_cast<std::size_t>(a)]);
      any = true;
    }
    (void)model;
    return any;
  };
  auto add_force = [&](const PointTerm& term, const Vec3& force) {
    if (!add_forces) return;
    for (int a = 0; a < 4; ++a) {
      const std::int32_t s = term.slot[static_cast<std::size_t>(a)];
      if (s >= 0 && free_[static_cast<std::size_t>(s)])
        Seg(f_, s) += term.w[static_cast<std::size_t>(a)] * force;
    }
  };
  if (contacts) {
    for (PointContact& c : *contacts) {
      if (c.target != PointContact::Target::kSoftBody) continue;
      c.force_n = 0;
      PointTerm term;
      Vec3 p;
      if (!make(c.target, c.index, c.nodes, c.weights, &term, &p)) continue;
      const double pen = c.offset_mm - c.normal.dot(p);
      if (!(pen > 0)) continue;
      const double k = c.stiffness_n_per_mm * units::kNewtonPerMmToInternal;
      add_force(term, (k * pen) * c.normal);
      term.k = k * (c.normal * c.normal.transpose());
      terms_.push_back(term);
      c.force_n = -1;  // marker: active this step (final value in FillOutputs)
    }
  }
  if (springs) {
    for (PointSpring& sp : *springs) {
      if (sp.target != PointContact::Target::kSoftBody) continue;
      sp.force_n = Vec3::Zero();
      PointTerm term;
      Vec3 p;
      if (!make(sp.target, sp.index, sp.nodes, sp.weights, &term, &p)) continue;
      const double k = sp.stiffness_n_per_mm * units::kNewtonPerMmToInternal;
      const Vec3 d = p - sp.anchor_mm;
      const double l = d.norm();
      if (l > 1e-12) {
        const Vec3 u = d / l;
        add_force(term, (-k * (l - sp.rest_length_mm)) * u);
        const Mat3 uu = u * u.transpose();
        // Geometric term clamped at zero so a compressed spring keeps A positive definite.
        const double geo = std::max(0.0, 1.0 - sp.rest_length_mm / l);
        term.k = k * (uu + geo * (Mat3::Identity() - uu));
      } else {
        term.k = k * Mat3::Identity();
      }
      terms_.push_back(term);
    }
  }
}

bool SoftSystem::ActivateCrossedContacts(double h, ContactSet* contacts) {
  const std::size_t first = terms_.size();
  for (PointContact& c : *contacts) {
    // force_n: -1 = active this step, 0 = apart at the start (BuildPointTerms).
    if (c.target != PointContact::Target::kSoftBody || c.force_n != 0) continue;
    if (c.index < 0 || static_cast<std::size_t>(c.index) >= bodies_.size()) continue;
    const Body& bd = bodies_[static_cast<std::size_t>(c.index)];
    PointTerm term;
    Vec3 p_start = Vec3::Zero(), p_end = Vec3::Zero();
    bool any = false;
    for (int a = 0; a < 4; ++a) {
      const std::int32_t n = c.nodes[static_cast<std::size_t>(a)];
      if (n < 0 || static_cast<std::size_t>(n) >= bd.slot.size()) continue;
      const std::int32_t s = bd.slot[static_cast<std::size_t>(n)];
      const double w = c.weights[static_cast<std::size_t>(a)];
      term.slot[static_cast<std::size_t>(a)] = s;
      term.w[static_cast<std::size_t>(a)] = w;
      p_start += w * Seg(x_, s);
      p_end += w * (Seg(x_, s) + h * (Seg(v_, s) + Seg(dv_, s)));
      any = true;
    }
    if (!any || !(c.offset_mm - c.normal.dot(p_end) > 0)) continue;
    const double k = c.stiffness_n_per_mm * units::kNewtonPerMmToInternal;
    term.k = k * (c.normal * c.normal.transpose());
    // Its share of b = h f - h^2 K_c v: the force linearised at the start (where it is apart,
    // so k * pen < 0) plus the stiffness gives k * pen at the end point, as for any term.
    const Vec3 force = (k * (c.offset_mm - c.normal.dot(p_start))) * c.normal;
    Vec3 pv = Vec3::Zero();
    for (int a = 0; a < 4; ++a) {
      const std::int32_t s = term.slot[static_cast<std::size_t>(a)];
      if (s >= 0) pv += term.w[static_cast<std::size_t>(a)] * Seg(v_, s);
    }
    const Vec3 rhs = h * force - (h * h) * (term.k * pv);
    for (int a = 0; a < 4; ++a) {
      const std::int32_t s = term.slot[static_cast<std::size_t>(a)];
      if (s >= 0 && free_[static_cast<std::size_t>(s)]) {
        Seg(f_, s) += term.w[static_cast<std::size_t>(a)] * force;
        Seg(b_, s) += term.w[static_cast<std::size_t>(a)] * rhs;
      }
    }
    terms_.push_back(term);
    c.force_n = -1;  // active from now on (final value in FillOutputs)
  }
  return terms_.size() > first;
}

void SoftSystem::ApplyStiffness(const Eigen::VectorXd& x, Eigen::VectorXd* y) const {
  if (product_ == SystemProduct::kAssembled) {
    kmat_.Multiply(x, free_, y);
    return;
  }
  ApplyElementStiffness(x, kscales_, y);
}

void SoftSystem::ApplyElementStiffness(const Eigen::VectorXd& x, const std::vector<double>& scales,
                                       Eigen::VectorXd* y) const {
  y->setZero();
  std::array<Vec3, 4> dx, out;
  for (std::size_t b = 0; b < bodies_.size(); ++b) {
    const Body& bd = bodies_[b];
    const double scale = scales[b];
    for (std::size_t t = 0; t < bd.rest.size(); ++t) {
      if (!bd.alive[t] || bd.rest[t].degenerate) continue;
      const auto& s = bd.tet_slot[t];
      for (int a = 0; a < 4; ++a) {
        dx[static_cast<std::size_t>(a)] = Seg(x, s[static_cast<std::size_t>(a)]);
        out[static_cast<std::size_t>(a)].setZero();
      }
      ElementStiffnessProduct(bd.rest[t], bd.rotation[t], bd.lame, scale, dx, &out);
      for (int a = 0; a < 4; ++a)
        Seg(*y, s[static_cast<std::size_t>(a)]) += out[static_cast<std::size_t>(a)];
    }
  }
  for (std::int32_t s = 0; s < slots_; ++s) {
    if (!free_[static_cast<std::size_t>(s)]) Seg(*y, s).setZero();
  }
}

void SoftSystem::ApplyPointTerms(double scale, const Eigen::VectorXd& x, Eigen::VectorXd* y) const {
  for (const PointTerm& t : terms_) {
    Vec3 p = Vec3::Zero();
    for (int a = 0; a < 4; ++a) {
      const std::int32_t s = t.slot[static_cast<std::size_t>(a)];
      if (s >= 0) p += t.w[static_cast<std::size_t>(a)] * Seg(x, s);
    }
    const Vec3 q = scale * (t.k * p);
    for (int a = 0; a < 4; ++a) {
      const std::int32_t s = t.slot[static_cast<std::size_t>(a)];
      if (s >= 0 && free_[static_cast<std::size_t>(s)])
        Seg(*y, s) += t.w[static_cast<std::size_t>(a)] * q;
    }
  }
}

void SoftSystem::ApplySystem(const Eigen::VectorXd& x, Eigen::VectorXd* y) const {
  ApplyStiffness(x, y);
  for (std::int32_t s = 0; s < slots_; ++s) {
    const auto i = static_cast<std::size_t>(s);
    if (free_[i]) Seg(*y, s) += (mass_[i] + h_ * alpha_mass_[i]) * Seg(x, s);
  }
  ApplyPointTerms(h_ * h_, x, y);
}

namespace {
using VecFn = std::function<void(const Eigen::VectorXd&, Eigen::VectorXd*)>;
class StepOperator final : public SpdOperator {
 public:
  StepOperator(VecFn apply, VecFn precondition)
      : apply_(std::move(apply)), precondition_(std::move(precondition)) {}
  void Apply(const Eigen::VectorXd& x, Eigen::VectorXd* y) const override { apply_(x, y); }
  void Precondition(const Eigen::VectorXd& r, Eigen::VectorXd* z) const override {
    precondition_(r, z);
  }

 private:
  VecFn apply_, precondition_;
};
}  // namespace

void SoftSystem::Scatter(State* state) const {
  for (std::size_t b = 0; b < bodies_.size(); ++b) {
    SoftBodyState& sb = state->soft_bodies[b];
    const Body& bd = bodies_[b];
    for (std::size_t i = 0; i < bd.slot.size(); ++i) {
      const std::int32_t s = bd.slot[i];
      const auto n = static_cast<Eigen::Index>(i);
      sb.x.col(n) = Seg(x_, s);
      sb.v.col(n) = Seg(v_, s);
      sb.dv_warm.col(n) = Seg(dv_, s);
    }
  }
}

void SoftSystem::FillOutputs(const Model& model, ContactSet* contacts, SpringSet* springs) const {
  (void)model;
  auto point = [&](std::int32_t index, const std::array<std::int32_t, 4>& nodes,
                   const std::array<double, 4>& w) {
    const Body& bd = bodies_[static_cast<std::size_t>(index)];
    Vec3 p = Vec3::Zero();
    for (int a = 0; a < 4; ++a) {
      const std::int32_t n = nodes[static_cast<std::size_t>(a)];
      if (n < 0 || static_cast<std::size_t>(n) >= bd.slot.size()) continue;
      p += w[static_cast<std::size_t>(a)] * Seg(x_, bd.slot[static_cast<std::size_t>(n)]);
    }
    return p;
  };
  if (contacts) {
    for (PointContact& c : *contacts) {
      if (c.target != PointContact::Target::kSoftBody || c.force_n >= 0) continue;
      // Active this step: the linearised penalty force at the new position (linear in p).
      const double pen = c.offset_mm - c.normal.dot(point(c.index, c.nodes, c.weights));
      c.force_n = std::max(0.0, c.stiffness_n_per_mm * pen);  // N/mm * mm = N
    }
  }
  if (springs) {
    for (PointSpring& sp : *springs) {
      if (sp.target != PointContact::Target::kSoftBody || sp.index < 0 ||
          static_cast<std::size_t>(sp.index) >= bodies_.size()) {
        continue;
      }
      const Vec3 d = point(sp.index, sp.nodes, sp.weights) - sp.anchor_mm;
      const double l = d.norm();
      sp.force_n = l > 1e-12 ? Vec3((-sp.stiffness_n_per_mm * (l - sp.rest_length_mm) / l) * d)
                             : Vec3::Zero();
    }
  }
}

SoftStepStats SoftSystem::Step(const Model& model, ContactSet* contacts, SpringSet* springs,
                               State* state) {
  SoftStepStats stats = Advance(model, model.options.dt_s, contacts, springs, state);
  if (stats.anchor_moved) RequestFactor(state);
  return stats;
}

void SoftSystem::RequestFactorAfter(const SoftStepStats& stats, State* state) {
  if (stats.anchor_moved && state->factor_switch_step < 0) RequestFactor(state);
}

SoftStepStats SoftSystem::Advance(const Model& model, double h_s, ContactSet* contacts,
                                  SpringSet* springs, State* state) {
  if (model.solver.integrator == Integrator::kArkode) {
    if (!arkode_) arkode_ = std::make_unique<ArkodeIntegrator>();
    return arkode_->Step(this, model, h_s, contacts, springs, state);
  }
  SoftStepStats stats;
  const auto t_start = Clock::now();
  const double h = h_s;
  // The preconditioner is always the one of the scenario's step: a shorter (sub)step solves
  // with it too (a worse but still symmetric positive definite preconditioner), so the factor
  // state machine in State never depends on whether a step was split.
  const double h_factor = model.options.dt_s;
  Gather(*state);
  ComputeRotationsAndForces(x_);
  AddGravity(model);
  stats.rotations_ms = MsSince(t_start);

  auto t0 = Clock::now();
  const bool assembled = product_ == SystemProduct::kAssembled;
  AssembleStiffness(h, h, assembled);
  BuildPointTerms(model, x_, contacts, springs, true);
  BuildPreconditioner(h_factor, state);
  if (h != h_factor) BuildBlockJacobi(h);  // the block-Jacobi fallback, for this h
  // b = h f - h (h + beta) K v - h alpha M v - h^2 C v on free slots.
  ApplyStiffness(v_, &tmp_);
  ApplyPointTerms(h * h, v_, &tmp_);
  for (std::int32_t s = 0; s < slots_; ++s) {
    const auto i = static_cast<std::size_t>(s);
    if (!free_[i]) {
      Seg(b_, s).setZero();
      continue;
    }
    Seg(b_, s) = h * Seg(f_, s) - Seg(tmp_, s) - (h * alpha_mass_[i]) * Seg(v_, s);
  }
  stats.assembly_ms = MsSince(t0);

  t0 = Clock::now();
  const StepOperator op(
      [this](const Eigen::VectorXd& x, Eigen::VectorXd* y) { ApplySystem(x, y); },
      [this](const Eigen::VectorXd& r, Eigen::VectorXd* z) { Precondition(r, z); });
  // Accuracy is set against the weight impulse h |W| as well as |b|: once the tissue hangs
  // balanced, |b| -> 0 and a residual relative to |b| alone would chase round-off.
  double m2 = 0;
  for (std::int32_t s = 0; s < slots_; ++s) {
    const auto i = static_cast<std::size_t>(s);
    if (free_[i]) m2 += mass_[i] * mass_[i];
  }
  const double reference = h * model.options.gravity_mm_s2.norm() * std::sqrt(m2);
  const CgResult cg = SolvePcg(op, b_, &dv_, model.solver.cg_max_iterations,
                               model.solver.cg_tolerance, reference, &cg_scratch_);
  CgResult last = cg;
  int cg_total = cg.iterations;
  // A contact apart at the start of the step but crossed by its end (a fast approach passes the
  // skin within one step) takes part from now on: its term enters the system and the step is
  // solved again from this solution, at most kCrossRounds times.
  for (int round = 0; round < kCrossRounds && contacts != nullptr; ++round) {
    if (!ActivateCrossedContacts(h, contacts)) break;
    if (!(preconditioner_ == Preconditioner::kRestCholesky && active_.ldlt.ok()) || uncovered_ > 0)
      BuildBlockJacobi(h);
    last = SolvePcg(op, b_, &dv_, model.solver.cg_max_iterations, model.solver.cg_tolerance,
                    reference, &cg_scratch_);
    cg_total += last.iterations;
    ++stats.contact_resolves;
  }
  stats.solve_ms = MsSince(t0);
  stats.cg_iterations = cg_total;
  stats.cg_relative_residual = last.relative_residual;
  stats.refactored = refactored_;
  stats.factor_ms = factor_ms_;
  stats.factor_work = factor_work_;
  if (new_factor_source_) state->factor_baseline_cg = cg.iterations;

  t0 = Clock::now();
  for (std::int32_t s = 0; s < slots_; ++s) {
    const auto i = static_cast<std::size_t>(s);
    if (free_[i]) {
      Seg(v_, s) += Seg(dv_, s);
      Seg(x_, s) += h * Seg(v_, s);
      ++stats.active_nodes;
    } else {
      Seg(v_, s).setZero();
      Seg(dv_, s).setZero();
    }
  }
  Scatter(state);
  FillOutputs(model, contacts, springs);
  if (preconditioner_ == Preconditioner::kRestCholesky && refactor_iterations_ > 0 &&
      cg.iterations > refactor_iterations_ &&
      (refactor_slack_ <= 0 || cg.iterations > state->factor_baseline_cg + refactor_slack_) &&
      state->factor_switch_step < 0) {
    // The factor has drifted from the current rotations (or mesh): the caller requests one of
    // the mesh and positions at the end of the step (RequestFactorAfter), used refactor_lag_
    // steps from now. Not while the step needs hardly more than the factor's first solve did:
    // those iterations come from the contact and spring terms, which a new factor leaves out.
    stats.anchor_moved = true;
  }
  stats.update_ms = MsSince(t0);
  for (const Body& bd : bodies_) {
    for (std::size_t t = 0; t < bd.rest.size(); ++t) {
      if (bd.alive[t] && !bd.rest[t].degenerate) ++stats.active_tets;
    }
  }
  stats.active_contacts = static_cast<std::int32_t>(terms_.size());
  stats.total_ms = MsSince(t_start);
  return stats;
}

// ------------------------------------------------------------------------------------------
// Stages of an external integrator (SoftStages)

void SoftSystem::BeginExternalStep(const State& state, Eigen::Ref<Eigen::VectorXd> x_mm,
                                   Eigen::Ref<Eigen::VectorXd> v_mm_s) {
  stage_state_ = &state;
  Gather(state);
  x_mm = x_;
  v_mm_s = v_;
}

void SoftSystem::EvaluateRates(const Model& model, const Eigen::VectorXd& x_mm,
                               const Eigen::VectorXd& v_mm_s, ContactSet* contacts,
                               SpringSet* springs, Eigen::Ref<Eigen::VectorXd> dx,
                               Eigen::Ref<Eigen::VectorXd> dv) {
  ComputeRotationsAndForces(x_mm);
  AddGravity(model);
  BuildPointTerms(model, x_mm, contacts, springs, true);
  std::vector<double> betas(bodies_.size());
  for (std::size_t b = 0; b < betas.size(); ++b) betas[b] = bodies_[b].beta;
  ApplyElementStiffness(v_mm_s, betas, &tmp_);
  for (std::int32_t k = 0; k < slots_; ++k) {
    const auto i = static_cast<std::size_t>(k);
    const Eigen::Index o = 3 * k;
    if (!free_[i]) {
      dx.segment<3>(o).setZero();
      dv.segment<3>(o).setZero();
      continue;
    }
    dx.segment<3>(o) = v_mm_s.segment<3>(o);
    dv.segment<3>(o) =
        (f_.segment<3>(o) - alpha_mass_[i] * v_mm_s.segment<3>(o) - tmp_.segment<3>(o)) / mass_[i];
  }
}

CgResult SoftSystem::SolveNewtonSystem(const Model& model, double gamma_s,
                                       const Eigen::VectorXd& xz_mm, const Eigen::VectorXd& bx,
                                       const Eigen::VectorXd& bv, ContactSet* contacts,
                                       SpringSet* springs, Eigen::Ref<Eigen::VectorXd> ox,
                                       Eigen::Ref<Eigen::VectorXd> ov) {
  const double gamma = gamma_s;
  ComputeRotationsAndForces(xz_mm);
  AssembleStiffness(gamma, gamma, product_ == SystemProduct::kAssembled);
  BuildPointTerms(model, xz_mm, nullptr, nullptr, false);
  BuildPointTerms(model, xz_mm, contacts, springs, false);
  BuildPreconditioner(gamma, const_cast<State*>(stage_state_));
  std::vector<double> ones(bodies_.size(), 1.0);
  ApplyElementStiffness(bx, ones, &tmp_);
  ApplyPointTerms(1.0, bx, &tmp_);
  for (std::int32_t k = 0; k < slots_; ++k) {
    const auto i = static_cast<std::size_t>(k);
    const Eigen::Index o = 3 * k;
    b_.segment<3>(o) =
        free_[i] ? Eigen::Vector3d(mass_[i] * bv.segment<3>(o) - gamma * tmp_.segment<3>(o))
                 : Eigen::Vector3d::Zero();
  }
  const StepOperator op(
      [this](const Eigen::VectorXd& x, Eigen::VectorXd* y) { ApplySystem(x, y); },
      [this](const Eigen::VectorXd& r, Eigen::VectorXd* z) { Precondition(r, z); });
  const CgResult cg =
      SolvePcg(op, b_, &dv_, model.solver.cg_max_iterations, model.solver.cg_tolerance);
  for (std::int32_t k = 0; k < slots_; ++k) {
    const Eigen::Index o = 3 * k;
    if (free_[static_cast<std::size_t>(k)]) {
      ov.segment<3>(o) = dv_.segment<3>(o);
      ox.segment<3>(o) = bx.segment<3>(o) + gamma * dv_.segment<3>(o);
    } else {
      ov.segment<3>(o) = bv.segment<3>(o);
      ox.segment<3>(o) = bx.segment<3>(o);
    }
  }
  return cg;
}

SoftStepStats SoftSystem::FinishExternalStep(const Model& model, const Eigen::VectorXd& x_mm,
                                             const Eigen::VectorXd& v_mm_s,
                                             const Eigen::VectorXd& v_old_mm_s,
                                             ContactSet* contacts, SpringSet* springs,
                                             State* state) {
  SoftStepStats stats;
  x_ = x_mm;
  v_ = v_mm_s;
  dv_ = v_ - v_old_mm_s;
  for (std::int32_t k = 0; k < slots_; ++k) {
    if (free_[static_cast<std::size_t>(k)]) {
      ++stats.active_nodes;
    } else {
      Seg(v_, k).setZero();
      Seg(dv_, k).setZero();
    }
  }
  Scatter(state);
  FillOutputs(model, contacts, springs);
  stats.active_contacts = static_cast<std::int32_t>(terms_.size());
  return stats;
}

}  // namespace arthrosim::physics
