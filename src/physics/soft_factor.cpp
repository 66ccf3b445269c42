// SoftSystem anchored factors: built from a source kept in State, prepared in parts over the
// steps of the refactorisation lag, switched in at State::factor_switch_step
// (docs/contact-model.md, "Deferred refactorisation").
#include <algorithm>
#include <array>
#include <utility>

#include "arthrosim/physics/polar_decomposition.h"
#include "arthrosim/physics/soft_system.h"
#include "soft_internal.h"

namespace arthrosim::physics {
using namespace soft_internal;  // NOLINT: this file is part of SoftSystem

namespace {

// Slots of a tet's nodes (-1 for a node past the source's nodes).
std::array<std::int32_t, 4> SourceSlots(const std::vector<std::int32_t>& slot, const mesh::Tet& tet,
                                        const Points& rest) {
  std::array<std::int32_t, 4> sl{-1, -1, -1, -1};
  for (int a = 0; a < 4; ++a) {
    const std::int32_t n = tet[static_cast<std::size_t>(a)];
    if (n >= 0 && n < rest.cols() && static_cast<std::size_t>(n) < slot.size())
      sl[static_cast<std::size_t>(a)] = slot[static_cast<std::size_t>(n)];
  }
  return sl;
}

// The rest data of tet t of a source mesh, or degenerate when it is not part of it (dead, past
// its end, a node past its nodes, two corners in one slot).
TetRest SourceTet(const mesh::Tet& tet, std::size_t t, const std::array<std::int32_t, 4>& slots,
                  const Points& rest, const std::vector<std::uint8_t>& alive) {
  if (t >= alive.size() || !alive[t]) return TetRest{};
  for (int a = 0; a < 4; ++a) {
    const std::int32_t n = tet[static_cast<std::size_t>(a)];
    if (n < 0 || n >= rest.cols() || slots[static_cast<std::size_t>(a)] < 0) return TetRest{};
    for (int c = 0; c < a; ++c) {
      if (slots[static_cast<std::size_t>(a)] == slots[static_cast<std::size_t>(c)]) return {};
    }
  }
  return ComputeTetRest(rest.col(tet[0]), rest.col(tet[1]), rest.col(tet[2]), rest.col(tet[3]));
}

}  // namespace

const std::vector<SoftSystem::FactorSource>& SoftSystem::ActiveSources(const State& state) {
  std::vector<FactorSource>& src = scratch_sources_;  // kept: no allocation per factor
  src.resize(bodies_.size());
  for (std::size_t b = 0; b < src.size(); ++b) {
    const SoftBodyState& sb = state.soft_bodies[b];
    src[b].rest = sb.factor_rest.cols() > 0 ? &sb.factor_rest : &sb.x_rest;
    src[b].alive = sb.factor_alive.empty() ? &sb.tet_alive : &sb.factor_alive;
    src[b].anchor = sb.x_factor.cols() > 0 ? &sb.x_factor : src[b].rest;
    src[b].tets = &sb.tets;
  }
  return src;
}

const std::vector<SoftSystem::FactorSource>& SoftSystem::PendingSources(const State& state) {
  std::vector<FactorSource>& src = scratch_sources_;
  src.resize(bodies_.size());
  for (std::size_t b = 0; b < src.size(); ++b) {
    const SoftBodyState& sb = state.soft_bodies[b];
    src[b] = FactorSource{&sb.factor_rest_next, &sb.factor_alive_next, &sb.x_factor_next, &sb.tets};
  }
  return src;
}

void SoftSystem::KeepFactorSource(SoftBodyState* sb) const {
  if (preconditioner_ != Preconditioner::kRestCholesky) return;
  if (sb->factor_rest.cols() == 0) sb->factor_rest = sb->x_rest;
  if (sb->factor_alive.empty()) sb->factor_alive = sb->tet_alive;
}

// The factor's unknowns (slots with an element of the source that are not fixed, in slot
// order) and its node pairs (the edges of those elements). Re-analyses the LDL^T pattern only
// when they differ from the last factor built in *f.
void SoftSystem::FactorPattern(const std::vector<FactorSource>& src, FactorBuild* f) {
  std::vector<std::uint8_t>& has = scratch_has_;
  std::vector<std::array<std::int32_t, 2>>& edges = scratch_edges_;
  has.assign(static_cast<std::size_t>(slots_), 0);
  edges.clear();
  for (std::size_t b = 0; b < bodies_.size(); ++b) {
    const Body& bd = bodies_[b];
    const auto& tets = src[b].tets;
    for (std::size_t t = 0; t < tets->size(); ++t) {
      const std::array<std::int32_t, 4> sl = SourceSlots(bd.slot, (*tets)[t], *src[b].rest);
      if (SourceTet((*tets)[t], t, sl, *src[b].rest, *src[b].alive).degenerate) continue;
      for (std::int32_t s : sl) has[static_cast<std::size_t>(s)] = 1;
      for (const auto& e : kTetEdges) {
        const std::int32_t si = sl[static_cast<std::size_t>(e[0])];
        const std::int32_t sj = sl[static_cast<std::size_t>(e[1])];
        edges.push_back({std::min(si, sj), std::max(si, sj)});
      }
    }
  }
  std::vector<std::int32_t>& compact = f->compact;
  std::vector<std::int32_t>& nodes = scratch_nodes_;
  compact.assign(static_cast<std::size_t>(slots_), -1);
  nodes.clear();
  for (std::int32_t s = 0; s < slots_; ++s) {
    if (has[static_cast<std::size_t>(s)] && !fixed_[static_cast<std::size_t>(s)]) {
      compact[static_cast<std::size_t>(s)] = static_cast<std::int32_t>(nodes.size());
      nodes.push_back(s);
    }
  }
  // The distinct pairs in ascending (i, j) order, by a counting sort on i and a sort of each
  // (short) row: the list a sort of all edges gives, at a fraction of its cost.
  const auto n_nodes = nodes.size();
  std::vector<std::int32_t>& row_at = scratch_row_at_;
  std::vector<std::int32_t>& cols = scratch_cols_;
  row_at.assign(n_nodes + 1, 0);
  for (const auto& e : edges) {
    const std::int32_t i = compact[static_cast<std::size_t>(e[0])];
    const std::int32_t j = compact[static_cast<std::size_t>(e[1])];
    if (i >= 0 && j >= 0) ++row_at[static_cast<std::size_t>(i) + 1];
  }
  for (std::size_t i = 0; i < n_nodes; ++i) row_at[i + 1] += row_at[i];
  cols.resize(static_cast<std::size_t>(row_at[n_nodes]));
  for (const auto& e : edges) {
    const std::int32_t i = compact[static_cast<std::size_t>(e[0])];
    const std::int32_t j = compact[static_cast<std::size_t>(e[1])];
    if (i >= 0 && j >= 0) cols[static_cast<std::size_t>(row_at[static_cast<std::size_t>(i)]++)] = j;
  }
  std::vector<std::array<std::int32_t, 2>>& pairs = scratch_pairs_;
  pairs.clear();
  std::size_t begin = 0;
  for (std::size_t i = 0; i < n_nodes; ++i) {  // row_at[i] is now the end of row i
    const auto end = static_cast<std::size_t>(row_at[i]);
    std::sort(cols.begin() + static_cast<std::ptrdiff_t>(begin),
              cols.begin() + static_cast<std::ptrdiff_t>(end));
    for (std::size_t k = begin; k < end; ++k) {
      if (k == begin || cols[k] != cols[k - 1])
        pairs.push_back({static_cast<std::int32_t>(i), cols[k]});  // slot order: i < j
    }
    begin = end;
  }
  if (f->analysed && nodes == f->nodes && pairs == f->pairs) return;
  f->nodes = nodes;
  f->pairs = pairs;
  const auto n = static_cast<std::int32_t>(f->nodes.size());
  f->row_start.assign(static_cast<std::size_t>(n) + 1, 0);
  for (const auto& p : f->pairs) ++f->row_start[static_cast<std::size_t>(p[0]) + 1];
  for (std::int32_t i = 0; i < n; ++i)
    f->row_start[static_cast<std::size_t>(i) + 1] += f->row_start[static_cast<std::size_t>(i)];
  f->ldlt.Analyze(n, f->pairs);
  f->analysed = true;
  f->diag.assign(static_cast<std::size_t>(n), Mat3::Zero());
  f->offdiag.assign(f->pairs.size(), Mat3::Zero());
}

// The step matrix of the source mesh with the element rotations of the anchor positions:
// elements in (body, tet) order, so every sum runs in the same order whatever the history.
void SoftSystem::FactorValues(const std::vector<FactorSource>& src, double h, FactorBuild* f) {
  for (Mat3& m : f->diag) m.setZero();
  for (Mat3& m : f->offdiag) m.setZero();
  f->anchor_rot.assign(static_cast<std::size_t>(slots_), Mat3::Zero());
  std::vector<double>& mass = scratch_mass_;
  std::vector<double>& alpha_mass = scratch_alpha_mass_;
  mass.assign(f->nodes.size(), 0.0);
  alpha_mass.assign(f->nodes.size(), 0.0);
  std::array<Mat3, 10> blocks;
  auto pair_index = [&](std::int32_t i, std::int32_t j) {
    const auto* b = f->pairs.data() + f->row_start[static_cast<std::size_t>(i)];
    const auto* e = f->pairs.data() + f->row_start[static_cast<std::size_t>(i) + 1];
    const auto* it = std::lower_bound(b, e, std::array<std::int32_t, 2>{i, j});
    return static_cast<std::size_t>(it - f->pairs.data());
  };
  for (std::size_t b = 0; b < bodies_.size(); ++b) {
    const Body& bd = bodies_[b];
    const double scale = h * (h + bd.beta);
    const auto& tets = src[b].tets;
    const Points& anchor = *src[b].anchor;
    const Points& rest = *src[b].rest;
    for (std::size_t t = 0; t < tets->size(); ++t) {
      const mesh::Tet& tet = (*tets)[t];
      const std::array<std::int32_t, 4> sl = SourceSlots(bd.slot, tet, rest);
      const TetRest r = SourceTet(tet, t, sl, rest, *src[b].alive);
      if (r.degenerate) continue;
      std::array<Vec3, 4> xa;
      for (int a = 0; a < 4; ++a) {
        const std::int32_t n = tet[static_cast<std::size_t>(a)];
        xa[static_cast<std::size_t>(a)] =
            n < anchor.cols() ? Vec3(anchor.col(n)) : Vec3(rest.col(n));
      }
      const Mat3 rot = PolarRotation(DeformationGradient(r, xa[0], xa[1], xa[2], xa[3]));
      ElementStiffnessBlocks(r, rot, bd.lame, scale, &blocks);
      const double q = bd.density * r.volume / 4.0;
      for (int a = 0; a < 4; ++a) {
        const auto si = static_cast<std::size_t>(sl[static_cast<std::size_t>(a)]);
        f->anchor_rot[si] += rot;
        const std::int32_t c = f->compact[si];
        if (c < 0) continue;
        f->diag[static_cast<std::size_t>(c)] += blocks[static_cast<std::size_t>(a)];
        mass[static_cast<std::size_t>(c)] += q;
        alpha_mass[static_cast<std::size_t>(c)] += bd.alpha * q;
      }
      for (int e = 0; e < 6; ++e) {
        const auto& ed = kTetEdges[static_cast<std::size_t>(e)];
        const std::int32_t si = sl[static_cast<std::size_t>(ed[0])];
        const std::int32_t sj = sl[static_cast<std::size_t>(ed[1])];
        const std::int32_t ci = f->compact[static_cast<std::size_t>(si)];
        const std::int32_t cj = f->compact[static_cast<std::size_t>(sj)];
        if (ci < 0 || cj < 0) continue;
        const Mat3& blk = blocks[static_cast<std::size_t>(4 + e)];  // rows si, columns sj
        if (ci < cj) {
          f->offdiag[pair_index(ci, cj)] += blk;
        } else {
          f->offdiag[pair_index(cj, ci)] += blk.transpose();
        }
      }
    }
  }
  for (std::size_t c = 0; c < f->nodes.size(); ++c) {
    const auto s = static_cast<std::size_t>(f->nodes[c]);
    f->anchor_rot[s] = PolarRotation(f->anchor_rot[s]);
    f->diag[c].diagonal().array() += mass[c] + h * alpha_mass[c];
  }
  f->h = h;
}

void SoftSystem::StartFactor(const std::vector<FactorSource>& src, double h, FactorBuild* f) {
  FactorPattern(src, f);
  FactorValues(src, h, f);
  f->ldlt.BeginFactor(f->diag, f->offdiag);
}

int SoftSystem::FactorParts() const { return std::max(1, refactor_lag_ - 2); }

// Work units of a requested factor: the start (pattern and values), then the numeric parts.
// Step R + j of a request made at step R (j = 1 ... lag - 1) has done min(j, units) of them; a
// lag of 2 or less does them all in its one step (or at the switch). After a restore the due
// units are caught up at once: only the time differs, never the bits.
void SoftSystem::AdvancePending(const State& state, double h, bool all) {
  const int parts = FactorParts();
  const int units = 1 + parts;
  const std::int64_t j = state.step - (state.factor_switch_step - refactor_lag_);
  const std::int64_t due = all || refactor_lag_ <= 2 ? units : std::min<std::int64_t>(j, units);
  while (pending_units_ < due) {
    if (pending_units_ == 0) {
      StartFactor(PendingSources(state), h, &pending_);
    } else {
      pending_.ldlt.FactorSlice(pending_units_ - 1, parts);
    }
    ++pending_units_;
    factor_work_ = true;
  }
}

// At the start of step State::factor_switch_step: the prepared factor replaces the one in use,
// and its source in State becomes the active one.
void SoftSystem::SwitchFactor(double h, State* state) {
  AdvancePending(*state, h, true);
  std::swap(active_, pending_);
  // Swapped, not moved: the arrays keep their storage for the next request (no allocation);
  // the *_next fields mean something only while State::factor_switch_step >= 0.
  for (SoftBodyState& sb : state->soft_bodies) {
    sb.x_factor.swap(sb.x_factor_next);
    sb.factor_rest.swap(sb.factor_rest_next);
    sb.factor_alive.swap(sb.factor_alive_next);
  }
  state->factor_switch_step = -1;
  pending_units_ = 0;
  refactored_ = true;
  new_factor_source_ = true;
}

void SoftSystem::RequestFactor(State* state) {
  for (SoftBodyState& sb : state->soft_bodies) {
    sb.x_factor_next = sb.x;
    sb.factor_rest_next = sb.x_rest;
    sb.factor_alive_next = sb.tet_alive;
  }
  state->factor_switch_step = state->step + refactor_lag_;
  pending_units_ = 0;
}

}  // namespace arthrosim::physics
