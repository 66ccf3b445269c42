// SoftSystem: build, slot layout and joins, element bookkeeping, topology changes.
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

SoftSystem::SoftSystem() = default;
SoftSystem::~SoftSystem() = default;
SoftSystem::SoftSystem(SoftSystem&&) noexcept = default;
SoftSystem& SoftSystem::operator=(SoftSystem&&) noexcept = default;

// ------------------------------------------------------------------------------------------
// Build and bookkeeping

void SoftSystem::Build(const Model& model, const State& state) {
  if (state.soft_bodies.size() != model.soft_bodies.size()) {
    throw InputError("", 0, "soft_bodies",
                     Cat({"state has ", std::to_string(state.soft_bodies.size()),
                          " soft bodies, model has ", std::to_string(model.soft_bodies.size())}));
  }
  arkode_.reset();
  product_ = model.solver.product;
  preconditioner_ = model.solver.preconditioner;
  refactor_iterations_ = model.solver.refactor_iterations;
  refactor_lag_ = std::max(1, model.solver.refactor_lag_steps);
  refactor_slack_ = model.solver.refactor_slack_iterations;
  active_ready_ = false;
  pending_units_ = 0;
  Layout(model, state);
  for (std::size_t b = 0; b < bodies_.size(); ++b) {
    const SoftBodyState& sb = state.soft_bodies[b];
    for (std::size_t t = 0; t < sb.tets.size(); ++t) {
      if (sb.tet_alive[t]) AddElement(static_cast<int>(b), static_cast<std::int32_t>(t), sb);
    }
  }
}

namespace {

// Throws InputError unless every soft body's node and tet arrays agree in size and every tet
// names nodes of its body.
void ValidateSoftState(const Model& model, const State& state) {
  for (std::size_t b = 0; b < model.soft_bodies.size(); ++b) {
    const SoftBodyState& sb = state.soft_bodies[b];
    const std::string where = Cat({"soft_bodies[", std::to_string(b), "]"});
    const auto n = static_cast<std::int32_t>(sb.x.cols());
    if (sb.v.cols() != n || sb.x_rest.cols() != n || sb.dv_warm.cols() != n ||
        sb.tet_alive.size() != sb.tets.size()) {
      throw InputError("", 0, where, "node or tet arrays of the state have different sizes");
    }
    for (const mesh::Tet& t : sb.tets) {
      for (std::int32_t k : t) {
        if (k < 0 || k >= n)
          throw InputError("", 0, Cat({where, ".tets"}), "node index out of range");
      }
    }
  }
}

}  // namespace

// Layout of the unknowns: each body's slot range, the per-slot arrays, joined nodes sharing
// their owner's slot, fixed nodes; then the step vectors sized to the slots.
void SoftSystem::Layout(const Model& model, const State& state) {
  ValidateSoftState(model, state);
  LayoutBodies(model, state);
  LayoutSlots();
  MatchJoins(model, state);
  MarkFixedNodes(model);
  ResetStepVectors();
}

// Per body: material, slot range (with room for split nodes) and per-tet arrays.
void SoftSystem::LayoutBodies(const Model& model, const State& state) {
  const std::size_t nb = model.soft_bodies.size();
  bodies_.assign(nb, Body{});
  std::int32_t offset = 0;
  for (std::size_t b = 0; b < nb; ++b) {
    const SoftBodyModel& bm = model.soft_bodies[b];
    const SoftBodyState& sb = state.soft_bodies[b];
    const auto n = static_cast<std::int32_t>(sb.x.cols());
    Body& body = bodies_[b];
    body.lame = LameFromMaterial(bm.material);
    body.density = bm.material.density_kg_m3 * units::kKgPerM3ToInternal;
    body.alpha = bm.material.rayleigh_mass;
    body.beta = bm.material.rayleigh_stiffness;
    body.offset = offset;
    body.capacity = n + n / 8 + 16;  // room for split nodes before a re-layout
    body.model_nodes =
        std::min<std::int32_t>(n, static_cast<std::int32_t>(bm.rest_mesh.nodes.cols()));
    body.slot.resize(static_cast<std::size_t>(n));
    body.owner.assign(static_cast<std::size_t>(n), 1);
    for (std::int32_t i = 0; i < n; ++i) body.slot[static_cast<std::size_t>(i)] = offset + i;
    const std::size_t nt = sb.tets.size();
    body.rest.assign(nt, TetRest{});
    body.tet_slot.assign(nt, {-1, -1, -1, -1});
    body.tet_pair.assign(nt, {-1, -1, -1, -1, -1, -1});
    body.alive.assign(sb.tet_alive.begin(), sb.tet_alive.end());
    body.rotation.assign(nt, Mat3::Identity());
    body.force.assign(nt, {Vec3::Zero(), Vec3::Zero(), Vec3::Zero(), Vec3::Zero()});
    offset += body.capacity;
  }
  slots_ = offset;
}

// Per-slot arrays for slots_ slots; every node owns its own slot (joins come after).
void SoftSystem::LayoutSlots() {
  const auto ns = static_cast<std::size_t>(slots_);
  slot_node_.assign(ns, NodeRef{});
  slot_aliases_.assign(ns, {});
  incident_.assign(ns, {});
  mass_.assign(ns, 0.0);
  alpha_mass_.assign(ns, 0.0);
  fixed_.assign(ns, 0);
  free_.assign(ns, 0);
  precond_.assign(ns, Mat3::Zero());
  node_rot_.assign(ns, Mat3::Identity());
  kmat_.Reset(slots_);
  for (std::size_t b = 0; b < bodies_.size(); ++b) {
    for (std::size_t i = 0; i < bodies_[b].slot.size(); ++i) {
      slot_node_[static_cast<std::size_t>(bodies_[b].slot[i])] =
          NodeRef{static_cast<std::int32_t>(b), static_cast<std::int32_t>(i)};
    }
  }
}

// Joins: a node of the later body coincident (at rest) with a node of the earlier body
// becomes an alias of it. Nearest candidate wins, ties by lower index.
void SoftSystem::MatchJoins(const Model& model, const State& state) {
  for (const Join& join : model.joins) {
    const int ia = model.FindSoftBody(join.body_a);
    const int ib = model.FindSoftBody(join.body_b);
    if (ia < 0 || ib < 0 || ia == ib) continue;
    const int early = std::min(ia, ib);
    const int late = std::max(ia, ib);
    Body& be = bodies_[static_cast<std::size_t>(early)];
    Body& bl = bodies_[static_cast<std::size_t>(late)];
    const Points& xe = state.soft_bodies[static_cast<std::size_t>(early)].x_rest;
    const Points& xl = state.soft_bodies[static_cast<std::size_t>(late)].x_rest;
    std::vector<std::pair<double, std::int32_t>> sorted;
    sorted.reserve(static_cast<std::size_t>(be.model_nodes));
    for (std::int32_t k = 0; k < be.model_nodes; ++k) sorted.emplace_back(xe(0, k), k);
    std::sort(sorted.begin(), sorted.end());  // (x, index): a total order
    const double tol = join.tolerance_mm;
    for (std::int32_t i = 0; i < bl.model_nodes; ++i) {
      if (!bl.owner[static_cast<std::size_t>(i)]) continue;
      const Vec3 p = xl.col(i);
      auto it = std::lower_bound(sorted.begin(), sorted.end(),
                                 std::make_pair(p.x() - tol, std::int32_t{-1}));
      std::int32_t best = -1;
      double best_d = tol;
      for (; it != sorted.end() && it->first <= p.x() + tol; ++it) {
        const double d = (xe.col(it->second) - p).norm();
        if (d <= best_d && (best < 0 || d < best_d || it->second < best)) {
          best = it->second;
          best_d = d;
        }
      }
      if (best < 0) continue;
      const std::int32_t own_slot = be.slot[static_cast<std::size_t>(best)];
      slot_node_[static_cast<std::size_t>(bl.slot[static_cast<std::size_t>(i)])] = NodeRef{};
      bl.slot[static_cast<std::size_t>(i)] = own_slot;
      bl.owner[static_cast<std::size_t>(i)] = 0;
      slot_aliases_[static_cast<std::size_t>(own_slot)].push_back(NodeRef{late, i});
    }
  }
  for (auto& aliases : slot_aliases_) {
    std::sort(aliases.begin(), aliases.end(), [](const NodeRef& a, const NodeRef& b) {
      return a.body != b.body ? a.body < b.body : a.node < b.node;
    });
  }
}

// Model fixed nodes: their slots never move. Throws InputError for an index out of range.
void SoftSystem::MarkFixedNodes(const Model& model) {
  const std::size_t nb = bodies_.size();
  for (std::size_t b = 0; b < nb; ++b) {
    const std::int32_t n = static_cast<std::int32_t>(bodies_[b].slot.size());
    for (std::int32_t k : model.soft_bodies[b].fixed_nodes) {
      if (k < 0 || k >= n) {
        throw InputError(
            "", 0, Cat({"soft_bodies[", std::to_string(b), "].fixed_nodes"}),
            Cat({"node index ", std::to_string(k), " out of range [0, ", std::to_string(n), ")"}));
      }
      fixed_[static_cast<std::size_t>(bodies_[b].slot[static_cast<std::size_t>(k)])] = 1;
    }
  }
}

void SoftSystem::ResetStepVectors() {
  x_.setZero(3 * slots_);
  v_.setZero(3 * slots_);
  f_.setZero(3 * slots_);
  b_.setZero(3 * slots_);
  dv_.setZero(3 * slots_);
  tmp_.setZero(3 * slots_);
}

void SoftSystem::RefreshRest(int body, std::int32_t tet, const SoftBodyState& sb) {
  Body& bd = bodies_[static_cast<std::size_t>(body)];
  const mesh::Tet& t = sb.tets[static_cast<std::size_t>(tet)];
  const auto& s = bd.tet_slot[static_cast<std::size_t>(tet)];
  TetRest rest = ComputeTetRest(sb.x_rest.col(t[0]), sb.x_rest.col(t[1]), sb.x_rest.col(t[2]),
                                sb.x_rest.col(t[3]));
  // Two corners in one slot (a join glued them): no element there.
  for (int a = 0; a < 4; ++a) {
    for (int c = a + 1; c < 4; ++c) {
      if (s[static_cast<std::size_t>(a)] == s[static_cast<std::size_t>(c)]) rest = TetRest{};
    }
  }
  bd.rest[static_cast<std::size_t>(tet)] = rest;
}

void SoftSystem::AddElement(int body, std::int32_t tet, const SoftBodyState& sb) {
  Body& bd = bodies_[static_cast<std::size_t>(body)];
  const mesh::Tet& t = sb.tets[static_cast<std::size_t>(tet)];
  auto& s = bd.tet_slot[static_cast<std::size_t>(tet)];
  for (int a = 0; a < 4; ++a)
    s[static_cast<std::size_t>(a)] =
        bd.slot[static_cast<std::size_t>(t[static_cast<std::size_t>(a)])];
  RefreshRest(body, tet, sb);
  auto& pairs = bd.tet_pair[static_cast<std::size_t>(tet)];
  for (int e = 0; e < 6; ++e) {
    const std::int32_t si = s[static_cast<std::size_t>(kTetEdges[static_cast<std::size_t>(e)][0])];
    const std::int32_t sj = s[static_cast<std::size_t>(kTetEdges[static_cast<std::size_t>(e)][1])];
    pairs[static_cast<std::size_t>(e)] = si == sj ? -1 : kmat_.AddPair(si, sj);
  }
  const ElemRef ref{body, tet};
  for (int a = 0; a < 4; ++a) {
    std::vector<ElemRef>& inc = incident_[static_cast<std::size_t>(s[static_cast<std::size_t>(a)])];
    auto it = std::lower_bound(inc.begin(), inc.end(), ref);
    if (it == inc.end() || !(*it == ref)) inc.insert(it, ref);
  }
  for (int a = 0; a < 4; ++a) RecomputeSlot(s[static_cast<std::size_t>(a)]);
}

void SoftSystem::RemoveElement(int body, std::int32_t tet) {
  Body& bd = bodies_[static_cast<std::size_t>(body)];
  auto& pairs = bd.tet_pair[static_cast<std::size_t>(tet)];
  for (std::int32_t& e : pairs) {
    if (e >= 0) kmat_.ReleasePair(e);
    e = -1;
  }
  const auto s = bd.tet_slot[static_cast<std::size_t>(tet)];
  const ElemRef ref{body, tet};
  for (int a = 0; a < 4; ++a) {
    std::vector<ElemRef>& inc = incident_[static_cast<std::size_t>(s[static_cast<std::size_t>(a)])];
    auto it = std::lower_bound(inc.begin(), inc.end(), ref);
    if (it != inc.end() && *it == ref) inc.erase(it);
  }
  bd.rest[static_cast<std::size_t>(tet)] = TetRest{};
  for (int a = 0; a < 4; ++a) RecomputeSlot(s[static_cast<std::size_t>(a)]);
}

void SoftSystem::RecomputeSlot(std::int32_t slot) {
  const auto s = static_cast<std::size_t>(slot);
  // Summed afresh in (body, tet) order: the same bits as a build from scratch.
  double m = 0, am = 0;
  int effective = 0;
  for (const ElemRef& r : incident_[s]) {
    const Body& bd = bodies_[static_cast<std::size_t>(r.body)];
    const TetRest& rest = bd.rest[static_cast<std::size_t>(r.tet)];
    if (rest.degenerate) continue;
    const double q = bd.density * rest.volume / 4.0;
    m += q;
    am += bd.alpha * q;
    ++effective;
  }
  mass_[s] = m;
  alpha_mass_[s] = am;
  free_[s] = (slot_node_[s].body >= 0 && effective > 0 && !fixed_[s]) ? 1 : 0;
}

bool SoftSystem::NeedsRebuild(int body, std::int32_t new_nodes) const {
  const Body& bd = bodies_[static_cast<std::size_t>(body)];
  return static_cast<std::int64_t>(bd.slot.size()) + new_nodes > bd.capacity;
}

// ------------------------------------------------------------------------------------------
// Topology changes

void SoftSystem::RemoveTets(int body, std::span<const std::int32_t> tets, State* state) {
  SoftBodyState& sb = state->soft_bodies[static_cast<std::size_t>(body)];
  KeepFactorSource(&sb);
  for (std::int32_t t : tets) {
    if (t < 0 || static_cast<std::size_t>(t) >= sb.tets.size()) continue;
    if (!sb.tet_alive[static_cast<std::size_t>(t)]) continue;
    sb.tet_alive[static_cast<std::size_t>(t)] = 0;
    bodies_[static_cast<std::size_t>(body)].alive[static_cast<std::size_t>(t)] = 0;
    RemoveElement(body, t);
  }
}

std::int32_t SoftSystem::AppendNodes(const Model& model, int body,
                                     std::span<const std::array<std::int32_t, 4>> parents,
                                     std::span<const std::array<double, 4>> weights, State* state) {
  SoftBodyState& sb = state->soft_bodies[static_cast<std::size_t>(body)];
  const auto n0 = static_cast<std::int32_t>(sb.x.cols());
  const auto k = static_cast<std::int32_t>(parents.size());
  KeepFactorSource(&sb);  // the factored mesh keeps its nodes: new ones are not in it
  Points x(3, n0 + k), v(3, n0 + k), xr(3, n0 + k), dw(3, n0 + k);
  x.leftCols(n0) = sb.x;
  v.leftCols(n0) = sb.v;
  xr.leftCols(n0) = sb.x_rest;
  dw.leftCols(n0) = sb.dv_warm;
  for (std::int32_t i = 0; i < k; ++i) {
    Vec3 px = Vec3::Zero(), pv = Vec3::Zero(), pr = Vec3::Zero(), pd = Vec3::Zero();
    for (int a = 0; a < 4; ++a) {
      const std::int32_t p = parents[static_cast<std::size_t>(i)][static_cast<std::size_t>(a)];
      const double w = weights[static_cast<std::size_t>(i)][static_cast<std::size_t>(a)];
      if (p < 0 || p >= n0 || w == 0) continue;
      px += w * sb.x.col(p);
      pv += w * sb.v.col(p);
      pr += w * sb.x_rest.col(p);
      pd += w * sb.dv_warm.col(p);
    }
    x.col(n0 + i) = px;
    v.col(n0 + i) = pv;
    xr.col(n0 + i) = pr;
    dw.col(n0 + i) = pd;
  }
  sb.x = std::move(x);
  sb.v = std::move(v);
  sb.x_rest = std::move(xr);
  sb.dv_warm = std::move(dw);
  if (NeedsRebuild(body, k)) {
    Build(model, *state);  // out of slot capacity: re-layout (same results, new room)
    return n0;
  }
  Body& bd = bodies_[static_cast<std::size_t>(body)];
  for (std::int32_t i = 0; i < k; ++i) {
    const std::int32_t slot = bd.offset + n0 + i;
    bd.slot.push_back(slot);
    bd.owner.push_back(1);
    slot_node_[static_cast<std::size_t>(slot)] = NodeRef{body, n0 + i};
    RecomputeSlot(slot);
  }
  return n0;
}

std::int32_t SoftSystem::AppendTets(int body, std::span<const mesh::Tet> tets, State* state) {
  SoftBodyState& sb = state->soft_bodies[static_cast<std::size_t>(body)];
  Body& bd = bodies_[static_cast<std::size_t>(body)];
  KeepFactorSource(&sb);
  const auto first = static_cast<std::int32_t>(sb.tets.size());
  const auto n = static_cast<std::int32_t>(sb.x.cols());
  for (const mesh::Tet& t : tets) {
    for (std::int32_t k : t) {
      if (k < 0 || k >= n) {
        throw InputError("", 0, Cat({"soft_bodies[", std::to_string(body), "].tets"}),
                         Cat({"appended tet uses node ", std::to_string(k), " out of range"}));
      }
    }
  }
  for (const mesh::Tet& t : tets) {
    const auto idx = static_cast<std::int32_t>(sb.tets.size());
    sb.tets.push_back(t);
    sb.tet_alive.push_back(1);
    bd.rest.emplace_back();
    bd.tet_slot.push_back({-1, -1, -1, -1});
    bd.tet_pair.push_back({-1, -1, -1, -1, -1, -1});
    bd.alive.push_back(1);
    bd.rotation.push_back(Mat3::Identity());
    bd.force.push_back({Vec3::Zero(), Vec3::Zero(), Vec3::Zero(), Vec3::Zero()});
    AddElement(body, idx, sb);
  }
  return first;
}

std::int32_t SoftSystem::SplitTet(const Model& model, int body, std::int32_t tet,
                                  const std::array<double, 4>& bary, State* state) {
  const mesh::Tet parent =
      state->soft_bodies[static_cast<std::size_t>(body)].tets[static_cast<std::size_t>(tet)];
  const std::array<std::array<std::int32_t, 4>, 1> parents{parent};
  const std::array<std::array<double, 4>, 1> weights{bary};
  const std::int32_t p = AppendNodes(model, body, parents, weights, state);
  const std::array<std::int32_t, 1> dead{tet};
  RemoveTets(body, dead, state);
  // Replacing one corner by an interior point keeps each child's orientation.
  const std::array<mesh::Tet, 4> children{{{p, parent[1], parent[2], parent[3]},
                                           {parent[0], p, parent[2], parent[3]},
                                           {parent[0], parent[1], p, parent[3]},
                                           {parent[0], parent[1], parent[2], p}}};
  return AppendTets(body, children, state);
}

void SoftSystem::SetRestPositions(int body, std::span<const std::int32_t> nodes,
                                  const Points& rest_mm, State* state) {
  Body& bd = bodies_[static_cast<std::size_t>(body)];
  for (SoftBodyState& sb : state->soft_bodies) KeepFactorSource(&sb);  // joined copies too
  std::vector<ElemRef> touched;
  for (std::size_t i = 0; i < nodes.size(); ++i) {
    const std::int32_t node = nodes[i];
    if (node < 0 || static_cast<std::size_t>(node) >= bd.slot.size()) continue;
    const std::int32_t slot = bd.slot[static_cast<std::size_t>(node)];
    const NodeRef own = slot_node_[static_cast<std::size_t>(slot)];
    state->soft_bodies[static_cast<std::size_t>(own.body)].x_rest.col(own.node) =
        rest_mm.col(static_cast<Eigen::Index>(i));
    for (const NodeRef& a : slot_aliases_[static_cast<std::size_t>(slot)]) {
      state->soft_bodies[static_cast<std::size_t>(a.body)].x_rest.col(a.node) =
          rest_mm.col(static_cast<Eigen::Index>(i));
    }
    const auto& inc = incident_[static_cast<std::size_t>(slot)];
    touched.insert(touched.end(), inc.begin(), inc.end());
  }
  std::sort(touched.begin(), touched.end());
  touched.erase(std::unique(touched.begin(), touched.end()), touched.end());
  std::vector<std::int32_t> slots;
  for (const ElemRef& r : touched) {
    RefreshRest(r.body, r.tet, state->soft_bodies[static_cast<std::size_t>(r.body)]);
    for (std::int32_t s :
         bodies_[static_cast<std::size_t>(r.body)].tet_slot[static_cast<std::size_t>(r.tet)]) {
      slots.push_back(s);
    }
  }
  std::sort(slots.begin(), slots.end());
  slots.erase(std::unique(slots.begin(), slots.end()), slots.end());
  for (std::int32_t s : slots) RecomputeSlot(s);
}

}  // namespace arthrosim::physics
