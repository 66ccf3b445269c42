#include "arthrosim/physics/soft_system.h"

#include <Eigen/Sparse>
#include <algorithm>
#include <cmath>
#include <ctime>
#include <functional>
#include <initializer_list>
#include <string>
#include <utility>

#include "arthrosim/core/error.h"
#include "arthrosim/core/parallel.h"
#include "arthrosim/core/units.h"
#include "arthrosim/physics/arkode_integrator.h"
#include "arthrosim/physics/cg_solver.h"
#include "arthrosim/physics/polar_decomposition.h"

namespace arthrosim::physics {
namespace {

// Stage timers read the CPU time of the process (all threads): on a shared machine it is far
// steadier than wall time, and for one thread it is the busy time of the step.
struct Clock {
  using time_point = double;  // ms
  static double now() {
    timespec ts{};
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return 1e3 * static_cast<double>(ts.tv_sec) + 1e-6 * static_cast<double>(ts.tv_nsec);
  }
};
double MsSince(double t0) { return Clock::now() - t0; }

inline auto Seg(Eigen::VectorXd& v, std::int32_t slot) {
  return v.segment<3>(3 * static_cast<Eigen::Index>(slot));
}
inline auto Seg(const Eigen::VectorXd& v, std::int32_t slot) {
  return v.segment<3>(3 * static_cast<Eigen::Index>(slot));
}

// Joins pieces by append (operator+ chains trip a GCC 12 -Wrestrict false positive).
std::string Cat(std::initializer_list<std::string> parts) {
  std::string out;
  for (const std::string& p : parts) out.append(p);
  return out;
}

constexpr std::int64_t kTetBlock = 128;  // fixed ParallelFor block (independent of threads)

}  // namespace

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
  pattern_dirty_ = true;
  rest_dirty_ = true;
  anchor_dirty_ = true;
  Layout(model, state);
  for (std::size_t b = 0; b < bodies_.size(); ++b) {
    const SoftBodyState& sb = state.soft_bodies[b];
    for (std::size_t t = 0; t < sb.tets.size(); ++t) {
      if (sb.tet_alive[t]) AddElement(static_cast<int>(b), static_cast<std::int32_t>(t), sb);
    }
  }
}

void SoftSystem::Layout(const Model& model, const State& state) {
  const std::size_t nb = model.soft_bodies.size();
  bodies_.assign(nb, Body{});
  std::int32_t offset = 0;
  for (std::size_t b = 0; b < nb; ++b) {
    const SoftBodyModel& bm = model.soft_bodies[b];
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
  anchor_rot_.assign(ns, Mat3::Identity());
  compact_.assign(ns, -1);
  kmat_.Reset(slots_);
  for (std::size_t b = 0; b < nb; ++b) {
    for (std::size_t i = 0; i < bodies_[b].slot.size(); ++i) {
      slot_node_[static_cast<std::size_t>(bodies_[b].slot[i])] =
          NodeRef{static_cast<std::int32_t>(b), static_cast<std::int32_t>(i)};
    }
  }

  // Joins: a node of the later body coincident (at rest) with a node of the earlier body
  // becomes an alias of it. Nearest candidate wins, ties by lower index.
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
  x_.setZero(3 * slots_);
  v_.setZero(3 * slots_);
  f_.setZero(3 * slots_);
  b_.setZero(3 * slots_);
  dv_.setZero(3 * slots_);
  tmp_.setZero(3 * slots_);
  xa_.setZero(3 * slots_);
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
  rest_dirty_ = true;
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
  pattern_dirty_ = true;
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
  rest_dirty_ = true;
  pattern_dirty_ = true;
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
  const bool has_anchor = sb.x_factor.cols() == n0 && n0 > 0;
  Points x(3, n0 + k), v(3, n0 + k), xr(3, n0 + k), dw(3, n0 + k);
  Points xf(3, has_anchor ? n0 + k : 0);
  if (has_anchor) xf.leftCols(n0) = sb.x_factor;
  x.leftCols(n0) = sb.x;
  v.leftCols(n0) = sb.v;
  xr.leftCols(n0) = sb.x_rest;
  dw.leftCols(n0) = sb.dv_warm;
  for (std::int32_t i = 0; i < k; ++i) {
    Vec3 px = Vec3::Zero(), pv = Vec3::Zero(), pr = Vec3::Zero(), pd = Vec3::Zero();
    Vec3 pf = Vec3::Zero();
    for (int a = 0; a < 4; ++a) {
      const std::int32_t p = parents[static_cast<std::size_t>(i)][static_cast<std::size_t>(a)];
      const double w = weights[static_cast<std::size_t>(i)][static_cast<std::size_t>(a)];
      if (p < 0 || p >= n0 || w == 0) continue;
      px += w * sb.x.col(p);
      pv += w * sb.v.col(p);
      pr += w * sb.x_rest.col(p);
      pd += w * sb.dv_warm.col(p);
      if (has_anchor) pf += w * sb.x_factor.col(p);
    }
    if (has_anchor) xf.col(n0 + i) = pf;
    x.col(n0 + i) = px;
    v.col(n0 + i) = pv;
    xr.col(n0 + i) = pr;
    dw.col(n0 + i) = pd;
  }
  sb.x = std::move(x);
  sb.v = std::move(v);
  sb.x_rest = std::move(xr);
  sb.dv_warm = std::move(dw);
  if (has_anchor) sb.x_factor = std::move(xf);
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
  pattern_dirty_ = true;
  return n0;
}

std::int32_t SoftSystem::AppendTets(int body, std::span<const mesh::Tet> tets, State* state) {
  SoftBodyState& sb = state->soft_bodies[static_cast<std::size_t>(body)];
  Body& bd = bodies_[static_cast<std::size_t>(body)];
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
    // Factor anchor: a change of any bit means a new factor (a pure function of State).
    const Vec3 a =
        r.node < sb.x_factor.cols() ? Vec3(sb.x_factor.col(r.node)) : Vec3(sb.x_rest.col(r.node));
    if (!(Seg(xa_, s).array() == a.array()).all()) {
      Seg(xa_, s) = a;
      anchor_dirty_ = true;
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
  if (model.solver.integrator == Integrator::kArkode) {
    if (!arkode_) arkode_ = std::make_unique<ArkodeIntegrator>();
    return arkode_->Step(this, model, contacts, springs, state);
  }
  SoftStepStats stats;
  const auto t_start = Clock::now();
  const double h = model.options.dt_s;
  Gather(*state);
  ComputeRotationsAndForces(x_);
  AddGravity(model);
  stats.rotations_ms = MsSince(t_start);

  auto t0 = Clock::now();
  const bool assembled = product_ == SystemProduct::kAssembled;
  AssembleStiffness(h, h, assembled);
  BuildPointTerms(model, x_, contacts, springs, true);
  BuildPreconditioner(h);
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
    if (!(preconditioner_ == Preconditioner::kRestCholesky && factor_.ok())) BuildBlockJacobi(h);
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
      cg.iterations > refactor_iterations_) {
    // The factor has drifted from the current rotations: anchor it at the new positions.
    for (SoftBodyState& sb : state->soft_bodies) sb.x_factor = sb.x;
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

}  // namespace arthrosim::physics
