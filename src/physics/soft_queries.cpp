// SoftSystem static equilibrium solve, energies, elastic forces and queries.
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

// ------------------------------------------------------------------------------------------
// Static solve, energies, queries

double SoftSystem::SolveStatic(const Model& model, State* state, int iterations) {
  Gather(*state);
  // Compact numbering of the free scalar unknowns in slot order.
  std::vector<Eigen::Index> index(static_cast<std::size_t>(slots_), -1);
  Eigen::Index n = 0;
  for (std::int32_t s = 0; s < slots_; ++s) {
    if (free_[static_cast<std::size_t>(s)]) index[static_cast<std::size_t>(s)] = 3 * n++;
  }
  Eigen::VectorXd fg = Eigen::VectorXd::Zero(3 * slots_);
  {
    f_.setZero();
    AddGravity(model);
    fg = f_;
  }
  const double fg_norm = fg.norm();
  double residual = 0;
  const SystemProduct saved = product_;
  for (int it = 0; it <= iterations; ++it) {
    ComputeRotationsAndForces(x_);
    AddGravity(model);
    residual = fg_norm > 0 ? f_.norm() / fg_norm : f_.norm();
    if (it == iterations) break;
    AssembleStiffness(0.0, 0.0, true);
    std::vector<Eigen::Triplet<double>> trip;
    trip.reserve(static_cast<std::size_t>(9 * (n + 2 * kmat_.pair_count())));
    auto put = [&](Eigen::Index r, Eigen::Index c, const Mat3& m) {
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) trip.emplace_back(r + i, c + j, m(i, j));
    };
    for (std::int32_t s = 0; s < slots_; ++s) {
      const Eigen::Index r = index[static_cast<std::size_t>(s)];
      if (r >= 0) put(r, r, kmat_.diag(s));
    }
    // Off-diagonal blocks: walk each element's pairs once per block via a visited mark.
    std::vector<std::uint8_t> seen;
    for (const Body& bd : bodies_) {
      for (std::size_t t = 0; t < bd.rest.size(); ++t) {
        if (!bd.alive[t]) continue;
        for (std::int32_t e : bd.tet_pair[t]) {
          if (e < 0) continue;
          if (static_cast<std::size_t>(e) >= seen.size())
            seen.resize(static_cast<std::size_t>(e) + 1, 0);
          if (seen[static_cast<std::size_t>(e)]) continue;
          seen[static_cast<std::size_t>(e)] = 1;
          const Eigen::Index r = index[static_cast<std::size_t>(kmat_.block_row(e))];
          const Eigen::Index c = index[static_cast<std::size_t>(kmat_.block_col(e))];
          if (r < 0 || c < 0) continue;
          put(r, c, kmat_.block(e));
          put(c, r, kmat_.block(e).transpose());
        }
      }
    }
    Eigen::SparseMatrix<double> k(3 * n, 3 * n);
    k.setFromTriplets(trip.begin(), trip.end());
    Eigen::VectorXd rhs(3 * n);
    for (std::int32_t s = 0; s < slots_; ++s) {
      const Eigen::Index r = index[static_cast<std::size_t>(s)];
      if (r >= 0) rhs.segment<3>(r) = Seg(f_, s);
    }
    Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(k);
    if (ldlt.info() != Eigen::Success) break;
    const Eigen::VectorXd du = ldlt.solve(rhs);
    for (std::int32_t s = 0; s < slots_; ++s) {
      const Eigen::Index r = index[static_cast<std::size_t>(s)];
      if (r >= 0) Seg(x_, s) += du.segment<3>(r);
    }
  }
  product_ = saved;
  v_.setZero();
  dv_.setZero();
  Scatter(state);
  return residual;
}

SoftEnergies SoftSystem::ComputeEnergies(const Model& model, const State& state) const {
  SoftEnergies e;
  const Vec3 g = model.options.gravity_mm_s2;
  for (std::int32_t s = 0; s < slots_; ++s) {
    const auto i = static_cast<std::size_t>(s);
    const NodeRef r = slot_node_[i];
    if (r.body < 0 || mass_[i] == 0) continue;
    const SoftBodyState& sb = state.soft_bodies[static_cast<std::size_t>(r.body)];
    e.kinetic_uj += 0.5 * mass_[i] * sb.v.col(r.node).squaredNorm();
    e.gravitational_uj -= mass_[i] * g.dot(sb.x.col(r.node));
  }
  for (std::size_t b = 0; b < bodies_.size(); ++b) {
    const Body& bd = bodies_[b];
    const SoftBodyState& sb = state.soft_bodies[b];
    for (std::size_t t = 0; t < bd.rest.size(); ++t) {
      if (!bd.alive[t] || bd.rest[t].degenerate) continue;
      const mesh::Tet& tt = sb.tets[t];
      const Mat3 f = DeformationGradient(bd.rest[t], sb.x.col(tt[0]), sb.x.col(tt[1]),
                                         sb.x.col(tt[2]), sb.x.col(tt[3]));
      e.elastic_uj += ElementEnergy(bd.rest[t], PolarRotation(f), f, bd.lame);
    }
  }
  return e;
}

Points SoftSystem::ElasticForces(const Model& model, const State& state, int body) const {
  (void)model;
  Eigen::VectorXd f = Eigen::VectorXd::Zero(3 * slots_);
  for (std::size_t b = 0; b < bodies_.size(); ++b) {
    const Body& bd = bodies_[b];
    const SoftBodyState& sb = state.soft_bodies[b];
    std::array<Vec3, 4> out;
    for (std::size_t t = 0; t < bd.rest.size(); ++t) {
      if (!bd.alive[t] || bd.rest[t].degenerate) continue;
      const mesh::Tet& tt = sb.tets[t];
      const Mat3 fg = DeformationGradient(bd.rest[t], sb.x.col(tt[0]), sb.x.col(tt[1]),
                                          sb.x.col(tt[2]), sb.x.col(tt[3]));
      ElementForces(bd.rest[t], PolarRotation(fg), fg, bd.lame, &out);
      for (int a = 0; a < 4; ++a)
        Seg(f, bd.tet_slot[t][static_cast<std::size_t>(a)]) += out[static_cast<std::size_t>(a)];
    }
  }
  const Body& bd = bodies_[static_cast<std::size_t>(body)];
  Points out(3, static_cast<Eigen::Index>(bd.slot.size()));
  for (std::size_t i = 0; i < bd.slot.size(); ++i)
    out.col(static_cast<Eigen::Index>(i)) = Seg(f, bd.slot[i]);
  return out;
}

double SoftSystem::NodeMass(int body, std::int32_t node) const {
  return mass_[static_cast<std::size_t>(
      bodies_[static_cast<std::size_t>(body)].slot[static_cast<std::size_t>(node)])];
}

double SoftSystem::TotalMass() const {
  double m = 0;
  for (double q : mass_) m += q;
  return m;
}

double SoftSystem::AliveVolume(int body) const {
  const Body& bd = bodies_[static_cast<std::size_t>(body)];
  double v = 0;
  for (std::size_t t = 0; t < bd.rest.size(); ++t) {
    if (bd.alive[t] && !bd.rest[t].degenerate) v += bd.rest[t].volume;
  }
  return v;
}

bool SoftSystem::IsFree(int body, std::int32_t node) const {
  return free_[static_cast<std::size_t>(
             bodies_[static_cast<std::size_t>(body)].slot[static_cast<std::size_t>(node)])] != 0;
}

NodeRef SoftSystem::Owner(int body, std::int32_t node) const {
  return slot_node_[static_cast<std::size_t>(
      bodies_[static_cast<std::size_t>(body)].slot[static_cast<std::size_t>(node)])];
}

bool SoftSystem::IsJoined(int body, std::int32_t node) const {
  const std::int32_t slot =
      bodies_[static_cast<std::size_t>(body)].slot[static_cast<std::size_t>(node)];
  const NodeRef own = slot_node_[static_cast<std::size_t>(slot)];
  return own.body != body || own.node != node ||
         !slot_aliases_[static_cast<std::size_t>(slot)].empty();
}

}  // namespace arthrosim::physics
