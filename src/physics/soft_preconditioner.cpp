// SoftSystem preconditioners: block Jacobi, and the warped anchored sparse LDL^T factor.
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
#include "arthrosim/physics/cg_solver.h"
#include "arthrosim/physics/polar_decomposition.h"
#include "soft_internal.h"

namespace arthrosim::physics {
using namespace soft_internal;  // NOLINT: this file is part of SoftSystem

void SoftSystem::BuildBlockJacobi(double h) {
  for (std::int32_t s = 0; s < slots_; ++s) {
    const auto i = static_cast<std::size_t>(s);
    if (!free_[i]) continue;
    precond_[i] = kmat_.diag(s);
    precond_[i].diagonal().array() += mass_[i] + h * alpha_mass_[i];
  }
  const double h2 = h * h;
  for (const PointTerm& t : terms_) {
    for (int a = 0; a < 4; ++a) {
      for (int c = 0; c < 4; ++c) {
        const std::int32_t sa = t.slot[static_cast<std::size_t>(a)];
        if (sa < 0 || sa != t.slot[static_cast<std::size_t>(c)] ||
            !free_[static_cast<std::size_t>(sa)])
          continue;
        precond_[static_cast<std::size_t>(sa)] +=
            (h2 * t.w[static_cast<std::size_t>(a)] * t.w[static_cast<std::size_t>(c)]) * t.k;
      }
    }
  }
  for (std::int32_t s = 0; s < slots_; ++s) {
    const auto i = static_cast<std::size_t>(s);
    if (!free_[i]) {
      precond_[i].setZero();
      continue;
    }
    const Mat3 inv = precond_[i].inverse();
    precond_[i] = inv.allFinite() ? inv : Mat3::Identity();
  }
}

void SoftSystem::BuildPreconditioner(double h, State* state) {
  refactored_ = false;
  new_factor_source_ = false;
  factor_work_ = false;
  factor_ms_ = 0;
  uncovered_ = 0;
  if (preconditioner_ == Preconditioner::kRestCholesky && state != nullptr) {
    const double t0 = Clock::now();
    if (!active_ready_ || active_.h != h) {  // after a build or restore, or a new h: at once
      StartFactor(ActiveSources(*state), h, &active_);
      active_.ldlt.FactorSlice(0, 1);
      active_ready_ = true;
      refactored_ = true;
      factor_work_ = true;
      new_factor_source_ = state->factor_baseline_cg < 0;  // no solve has used a factor yet
    }
    if (state->factor_switch_step >= 0) {
      if (state->step >= state->factor_switch_step) {
        SwitchFactor(h, state);
      } else {
        AdvancePending(*state, h, false);
      }
    }
    if (active_.ldlt.ok() && CountUncovered() > 0) {
      // Nodes added since the factor's mesh (a cut's split nodes): block Jacobi on them beside
      // the factor converges badly (strongly coupled to the factored nodes), so the mesh of this
      // step is factored at once, at the positions of its start (any pending one is dropped).
      ReplaceFactorNow(h, state);
    }
    factor_ms_ = factor_work_ ? MsSince(t0) : 0.0;
    if (active_.ldlt.ok()) {
      WarpFactor();
      if (uncovered_ > 0) BuildBlockJacobi(h);
      return;
    }
  }
  BuildBlockJacobi(h);
}

std::int32_t SoftSystem::CountUncovered() const {
  std::int32_t n = 0;
  for (std::int32_t s = 0; s < slots_; ++s) {
    const auto i = static_cast<std::size_t>(s);
    if (free_[i] && active_.compact[i] < 0) ++n;
  }
  return n;
}

void SoftSystem::ReplaceFactorNow(double h, State* state) {
  for (SoftBodyState& sb : state->soft_bodies) {
    sb.x_factor = sb.x;
    sb.factor_rest = sb.x_rest;
    sb.factor_alive = sb.tet_alive;
  }
  state->factor_switch_step = -1;
  pending_units_ = 0;
  StartFactor(ActiveSources(*state), h, &active_);
  active_.ldlt.FactorSlice(0, 1);
  refactored_ = true;
  new_factor_source_ = true;
  factor_work_ = true;
}

// Warp: the current node rotation (polar of the sum of incident element rotations, in (body,
// tet) order) times the inverse anchor rotation, for the free slots the factor covers; counts
// the free slots it does not cover (new nodes since its mesh: block Jacobi).
void SoftSystem::WarpFactor() {
  // Sums by one pass over the elements in (body, tet) order, which is each slot's incident
  // order, so every sum is added in the same order as over its incident list (a slot that a
  // merged tet holds twice counts that tet once).
  node_sum_.assign(static_cast<std::size_t>(slots_), Mat3::Zero());
  for (const Body& bd : bodies_) {
    for (std::size_t t = 0; t < bd.rest.size(); ++t) {
      if (!bd.alive[t] || bd.rest[t].degenerate) continue;
      const auto& sl = bd.tet_slot[t];
      for (int a = 0; a < 4; ++a) {
        const std::int32_t slot = sl[static_cast<std::size_t>(a)];
        bool repeated = false;
        for (int q = 0; q < a; ++q) repeated = repeated || sl[static_cast<std::size_t>(q)] == slot;
        if (!repeated && free_[static_cast<std::size_t>(slot)])
          node_sum_[static_cast<std::size_t>(slot)] += bd.rotation[t];
      }
    }
  }
  const std::vector<std::int32_t>& compact = active_.compact;
  ParallelFor(slots_, 256, [&](std::int64_t begin, std::int64_t end) {
    // Side by side (vectorised); each lane's result depends on its own matrix only.
    const auto b = static_cast<std::size_t>(begin);
    PolarRotations(node_sum_.data() + b, node_rot_.data() + b, static_cast<int>(end - begin));
    for (std::int64_t s = begin; s < end; ++s) {
      const auto i = static_cast<std::size_t>(s);
      if (compact[i] >= 0) node_rot_[i] = Mat3(node_rot_[i] * active_.anchor_rot[i].transpose());
    }
  });
  uncovered_ = CountUncovered();
  pw_.setZero(3 * static_cast<Eigen::Index>(active_.nodes.size()));
}

void SoftSystem::Precondition(const Eigen::VectorXd& r, Eigen::VectorXd* z) const {
  if (preconditioner_ == Preconditioner::kRestCholesky && active_.ldlt.ok()) {
    // Factor nodes no longer free (their elements were removed since) take 0 and give nothing:
    // a principal part of the factor's inverse, still positive definite.
    const std::vector<std::int32_t>& compact = active_.compact;
    for (std::int32_t s = 0; s < slots_; ++s) {
      const auto i = static_cast<std::size_t>(s);
      const std::int32_t c = compact[i];
      if (c < 0) continue;
      pw_.segment<3>(3 * c) =
          free_[i] ? Vec3(node_rot_[i].transpose() * Seg(r, s)) : Vec3(Vec3::Zero());
    }
    active_.ldlt.Solve(pw_.data());
    for (std::int32_t s = 0; s < slots_; ++s) {
      const auto i = static_cast<std::size_t>(s);
      const std::int32_t c = compact[i];
      if (!free_[i]) {
        Seg(*z, s).setZero();
      } else if (c >= 0) {
        Seg(*z, s) = node_rot_[i] * pw_.segment<3>(3 * c);
      } else {
        Seg(*z, s) = precond_[i] * Seg(r, s);
      }
    }
    return;
  }
  for (std::int32_t s = 0; s < slots_; ++s) {
    Seg(*z, s) = precond_[static_cast<std::size_t>(s)] * Seg(r, s);
  }
}

}  // namespace arthrosim::physics
