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

void SoftSystem::BuildPreconditioner(double h) {
  refactored_ = false;
  factor_ms_ = 0;
  if (preconditioner_ == Preconditioner::kRestCholesky) {
    const double t0 = Clock::now();
    if (pattern_dirty_) AnalyzeFactor();
    if (rest_dirty_ || anchor_dirty_ || factor_h_ != h) FactorRestSystem(h);
    factor_ms_ = refactored_ ? MsSince(t0) : 0.0;
    if (factor_.ok()) {
      // Warp: the current node rotation (polar of the sum of incident element rotations, in
      // (body, tet) order) times the inverse anchor rotation.
      // Sums by one pass over the elements in (body, tet) order, which is each slot's incident
      // order, so every sum is added in the same order as over its incident list (a slot that
      // a merged tet holds twice counts that tet once).
      node_sum_.assign(static_cast<std::size_t>(slots_), Mat3::Zero());
      for (const Body& bd : bodies_) {
        for (std::size_t t = 0; t < bd.rest.size(); ++t) {
          if (!bd.alive[t] || bd.rest[t].degenerate) continue;
          const auto& sl = bd.tet_slot[t];
          for (int a = 0; a < 4; ++a) {
            const std::int32_t slot = sl[static_cast<std::size_t>(a)];
            bool repeated = false;
            for (int q = 0; q < a; ++q)
              repeated = repeated || sl[static_cast<std::size_t>(q)] == slot;
            if (!repeated && free_[static_cast<std::size_t>(slot)])
              node_sum_[static_cast<std::size_t>(slot)] += bd.rotation[t];
          }
        }
      }
      ParallelFor(slots_, 256, [&](std::int64_t begin, std::int64_t end) {
        // Side by side (vectorised); each lane's result depends on its own matrix only.
        const auto b = static_cast<std::size_t>(begin);
        PolarRotations(node_sum_.data() + b, node_rot_.data() + b, static_cast<int>(end - begin));
        for (std::int64_t s = begin; s < end; ++s) {
          const auto i = static_cast<std::size_t>(s);
          node_rot_[i] = Mat3(node_rot_[i] * anchor_rot_[i].transpose());
        }
      });
      return;
    }
  }
  BuildBlockJacobi(h);
}

void SoftSystem::AnalyzeFactor() {
  // Unknowns: free slots in slot order; pairs: kmat_'s live pairs between free slots (indexed
  // like kmat_'s blocks, but the pattern and ordering depend on the set of pairs only).
  std::int32_t n = 0;
  for (std::int32_t s = 0; s < slots_; ++s)
    compact_[static_cast<std::size_t>(s)] = free_[static_cast<std::size_t>(s)] ? n++ : -1;
  std::vector<std::array<std::int32_t, 2>> pairs(static_cast<std::size_t>(kmat_.block_capacity()),
                                                 std::array<std::int32_t, 2>{-1, -1});
  for (std::int32_t e = 0; e < kmat_.block_capacity(); ++e) {
    if (!kmat_.block_live(e)) continue;
    const std::int32_t r = compact_[static_cast<std::size_t>(kmat_.block_row(e))];
    const std::int32_t c = compact_[static_cast<std::size_t>(kmat_.block_col(e))];
    if (r >= 0 && c >= 0) pairs[static_cast<std::size_t>(e)] = {r, c};
  }
  factor_.Analyze(n, pairs);
  fdiag_.assign(static_cast<std::size_t>(n), Mat3::Zero());
  fpair_.assign(pairs.size(), Mat3::Zero());
  pw_.setZero(3 * static_cast<Eigen::Index>(n));
  pattern_dirty_ = false;
  rest_dirty_ = true;
}

void SoftSystem::FactorRestSystem(double h) {
  // The step matrix with the element rotations of the anchor positions. A function of rest
  // data, topology, h and the anchor only, so it is identical after a restore.
  refactored_ = true;
  rest_dirty_ = false;
  anchor_dirty_ = false;
  factor_h_ = h;
  for (Mat3& m : fdiag_) m.setZero();
  for (Mat3& m : fpair_) m.setZero();
  for (Mat3& m : anchor_rot_) m.setZero();
  std::array<Mat3, 10> blocks;
  for (const Body& bd : bodies_) {
    const double scale = h * (h + bd.beta);
    for (std::size_t t = 0; t < bd.rest.size(); ++t) {
      if (!bd.alive[t] || bd.rest[t].degenerate) continue;
      const auto& sl = bd.tet_slot[t];
      const Mat3 f = DeformationGradient(bd.rest[t], Seg(xa_, sl[0]), Seg(xa_, sl[1]),
                                         Seg(xa_, sl[2]), Seg(xa_, sl[3]));
      const Mat3 rot = PolarRotation(f);
      ElementStiffnessBlocks(bd.rest[t], rot, bd.lame, scale, &blocks);
      for (int a = 0; a < 4; ++a) {
        const auto si = static_cast<std::size_t>(sl[static_cast<std::size_t>(a)]);
        anchor_rot_[si] += rot;
        const std::int32_t c = compact_[si];
        if (c >= 0) fdiag_[static_cast<std::size_t>(c)] += blocks[static_cast<std::size_t>(a)];
      }
      for (int e = 0; e < 6; ++e) {
        const std::int32_t idx = bd.tet_pair[t][static_cast<std::size_t>(e)];
        if (idx < 0) continue;
        const std::int32_t si =
            sl[static_cast<std::size_t>(kTetEdges[static_cast<std::size_t>(e)][0])];
        const std::int32_t sj =
            sl[static_cast<std::size_t>(kTetEdges[static_cast<std::size_t>(e)][1])];
        if (si < sj) {
          fpair_[static_cast<std::size_t>(idx)] += blocks[static_cast<std::size_t>(4 + e)];
        } else {
          fpair_[static_cast<std::size_t>(idx)] +=
              blocks[static_cast<std::size_t>(4 + e)].transpose();
        }
      }
    }
  }
  for (std::int32_t s = 0; s < slots_; ++s) {
    const auto i = static_cast<std::size_t>(s);
    anchor_rot_[i] = PolarRotation(anchor_rot_[i]);
    const std::int32_t c = compact_[i];
    if (c >= 0)
      fdiag_[static_cast<std::size_t>(c)].diagonal().array() += mass_[i] + h * alpha_mass_[i];
  }
  factor_.Factor(fdiag_, fpair_);
}

void SoftSystem::Precondition(const Eigen::VectorXd& r, Eigen::VectorXd* z) const {
  if (preconditioner_ == Preconditioner::kRestCholesky && factor_.ok()) {
    for (std::int32_t s = 0; s < slots_; ++s) {
      const std::int32_t c = compact_[static_cast<std::size_t>(s)];
      if (c >= 0)
        pw_.segment<3>(3 * c) = node_rot_[static_cast<std::size_t>(s)].transpose() * Seg(r, s);
    }
    factor_.Solve(pw_.data());
    for (std::int32_t s = 0; s < slots_; ++s) {
      const std::int32_t c = compact_[static_cast<std::size_t>(s)];
      if (c >= 0) {
        Seg(*z, s) = node_rot_[static_cast<std::size_t>(s)] * pw_.segment<3>(3 * c);
      } else {
        Seg(*z, s).setZero();
      }
    }
    return;
  }
  for (std::int32_t s = 0; s < slots_; ++s) {
    Seg(*z, s) = precond_[static_cast<std::size_t>(s)] * Seg(r, s);
  }
}

}  // namespace arthrosim::physics
