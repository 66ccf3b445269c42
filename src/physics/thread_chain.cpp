#include "arthrosim/physics/thread_chain.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "arthrosim/core/units.h"
#include "thread_internal.h"

namespace arthrosim::physics {

namespace {

using thread_internal::System;
using thread_internal::Term;

// The node range [first, end) of thread t in the global numbering.
int ThreadEnd(const System& s, int t, int nt) { return t + 1 < nt ? s.offset[t + 1] : s.num_nodes; }

// ---- Global numbering: threads concatenated; every buffer lives in ws->scratch and keeps its
// capacity.
void NumberNodes(const std::vector<ThreadModel>& threads, const std::vector<ThreadState>& states,
                 const std::vector<ThreadRest>& rests, double dt_s, const Vec3& gravity_mm_s2,
                 System* sys) {
  System& s = *sys;
  const int nt = static_cast<int>(threads.size());
  s.dt = dt_s;
  s.gravity = gravity_mm_s2;
  s.num_nodes = 0;
  s.num_free = 0;
  s.offset.resize(nt);
  for (int t = 0; t < nt; ++t) {
    s.offset[t] = s.num_nodes;
    s.num_nodes += static_cast<int>(states[t].x.cols());
  }
  s.x0.resize(3, s.num_nodes);
  s.v0.resize(3, s.num_nodes);
  s.dof.assign(s.num_nodes, -1);
  s.alive.assign(s.num_nodes, 0);
  s.mass.assign(s.num_nodes, 0.0);
  s.inertia.assign(s.num_nodes, 0.0);
  s.min_pivot.assign(s.num_nodes, 0.0);
  for (int t = 0; t < nt; ++t) {
    const ThreadState& st = states[t];
    const ThreadRest& r = rests[t];
    const int n = static_cast<int>(st.x.cols());
    if (n != static_cast<int>(r.mass_kg.size()) || st.v.cols() != n ||
        static_cast<int>(st.node_alive.size()) != n)
      throw std::invalid_argument("StepThreads: thread '" + threads[t].name +
                                  "' state does not match its model");
    for (int i = 0; i < n; ++i) {
      const int g = s.offset[t] + i;
      s.x0.col(g) = st.x.col(i);
      s.v0.col(g) = st.v.col(i);
      s.alive[g] = st.node_alive[i];
      s.mass[g] = r.mass_kg[i];
      s.inertia[g] = r.mass_kg[i] * (1 + threads[t].damping_per_s * dt_s) / (dt_s * dt_s);
      if (s.alive[g] && !r.fixed[i]) s.dof[g] = s.num_free++;
      // The matrix is inertia + positive semi-definite terms, so its pivots are >= the
      // inertia; a pivot far below it means the negative geometric terms made it indefinite.
      s.min_pivot[g] = s.dof[g] >= 0 ? 1e-3 * s.inertia[g] : 0.5;
    }
  }
}

// ---- Internal terms: stretch (one per alive segment, chain order) and bending.
void AddInternalTerms(const std::vector<ThreadModel>& threads, const std::vector<ThreadRest>& rests,
                      const ThreadSolverParams& p, System* sys) {
  System& s = *sys;
  s.stretch_terms.clear();
  s.fixed_terms.clear();
  s.pair_terms.clear();
  s.pair_keys.clear();
  s.segments.clear();
  s.seg_diameter.clear();
  for (int t = 0; t < static_cast<int>(threads.size()); ++t) {
    const ThreadModel& m = threads[t];
    const ThreadRest& r = rests[t];
    const int n = static_cast<int>(r.mass_kg.size());
    const double ea = m.stretch_stiffness_n * units::kNewtonToInternalForce;   // mN
    const double ei = m.bend_stiffness_n_mm2 * units::kNewtonToInternalForce;  // mN mm^2
    for (int i = 0; i + 1 < n; ++i) {
      const int g0 = s.offset[t] + i, g1 = g0 + 1;
      if (!s.alive[g0] || !s.alive[g1]) continue;
      Term term;
      term.kind = Term::Kind::kSpring;
      term.count = 2;
      term.node = {g0, g1, -1, -1};
      term.w = {-1, 1, 0, 0};
      term.k = ea / r.rest_length_mm[i];
      term.k_compress = p.compression_stiffness_fraction * term.k;
      term.scalar = r.rest_length_mm[i];
      s.stretch_terms.push_back(term);
      s.segments.push_back(ThreadSegmentRef{t, i, g0, g1});
      s.seg_diameter.push_back(m.diameter_mm);
    }
    if (ei > 0) {
      for (int i = 1; i + 1 < n; ++i) {
        const int g = s.offset[t] + i;
        if (!s.alive[g - 1] || !s.alive[g] || !s.alive[g + 1]) continue;
        const double l0 = r.rest_length_mm[i - 1], l1 = r.rest_length_mm[i];
        Term term;
        term.kind = Term::Kind::kSpring;
        term.count = 3;
        term.node = {g - 1, g, g + 1, -1};
        term.w = {1 / l0, -(1 / l0 + 1 / l1), 1 / l1, 0};
        term.k = ei / (0.5 * (l0 + l1));
        term.scalar = 0;
        s.fixed_terms.push_back(term);
      }
    }
  }
}

// One fixed term per thread point of `points` (PointContacts or PointSprings; other targets are
// skipped): of `kind`, with the point's stiffness and its members `vec` and `scalar`;
// (*term_of)[c] is point c's term (-1 for none). `what` names the type in the range error.
template <class P>
void AddPointTerms(const std::vector<ThreadRest>& rests, const std::vector<P>& points,
                   Term::Kind kind, const char* what, Vec3 P::*vec, double P::*scalar,
                   std::vector<int>* term_of, System* sys) {
  System& s = *sys;
  const int nt = static_cast<int>(rests.size());
  for (std::size_t c = 0; c < points.size(); ++c) {
    const P& pt = points[c];
    if (pt.target != PointContact::Target::kThread) continue;
    if (pt.index < 0 || pt.index >= nt)
      throw std::invalid_argument(std::string(what) + " thread index out of range");
    Term term;
    term.kind = kind;
    if (!thread_internal::PointTerm(s, pt.index, pt.nodes, pt.weights,
                                    static_cast<int>(rests[pt.index].mass_kg.size()), &term))
      continue;
    term.k = pt.stiffness_n_per_mm * units::kNewtonPerMmToInternal;
    term.vec = pt.*vec;
    term.scalar = pt.*scalar;
    (*term_of)[c] = static_cast<int>(s.fixed_terms.size());
    s.fixed_terms.push_back(term);
  }
}

// ---- External contacts and springs (targets kThread only), remembered per contact / spring
// for the force outputs.
void AddExternalTerms(const std::vector<ThreadRest>& rests, const ContactSet* contacts,
                      const SpringSet* springs, System* sys) {
  System& s = *sys;
  s.contact_term.assign(contacts ? contacts->size() : 0, -1);
  s.spring_term.assign(springs ? springs->size() : 0, -1);
  if (contacts) {
    AddPointTerms(rests, *contacts, Term::Kind::kPlane, "PointContact", &PointContact::normal,
                  &PointContact::offset_mm, &s.contact_term, sys);
  }
  if (springs) {
    AddPointTerms(rests, *springs, Term::Kind::kSpring, "PointSpring", &PointSpring::anchor_mm,
                  &PointSpring::rest_length_mm, &s.spring_term, sys);
  }
}

// ---- Speed barrier: each free node stays within vmax dt of its start (paper's anti-jitter
// limit), inside the solve so that the chain keeps its length while it is slowed down.
void AddSpeedBarriers(const std::vector<ThreadModel>& threads, const ThreadSolverParams& p,
                      System* sys) {
  System& s = *sys;
  const int nt = static_cast<int>(threads.size());
  for (int t = 0; t < nt; ++t) {
    const double vmax = threads[t].max_speed_mm_s;
    if (!(vmax > 0)) continue;
    for (int i = s.offset[t]; i < ThreadEnd(s, t, nt); ++i) {
      if (s.dof[i] < 0) continue;
      Term term;
      term.kind = Term::Kind::kLimit;
      term.count = 1;
      term.node = {i, -1, -1, -1};
      term.w = {1, 0, 0, 0};
      term.k = p.speed_barrier_stiffness_n_per_mm * units::kNewtonPerMmToInternal;
      term.vec = s.x0.col(i);
      term.scalar = vmax * s.dt;
      s.fixed_terms.push_back(term);
    }
  }
}

// A segment-segment contact term for the pair (a, b) (stiffness kc, mN/mm), kept sorted by pair;
// false if the pair already has one.
bool AddPairTerm(System* sys, double kc, int a, int b, const SegmentClosest& cp, const Vec3& a0,
                 const Vec3& a1, const Vec3& b0, const Vec3& b1) {
  System& s = *sys;
  const std::array<int, 2> key{a, b};
  auto it = std::lower_bound(s.pair_keys.begin(), s.pair_keys.end(), key);
  if (it != s.pair_keys.end() && *it == key) return false;
  const std::size_t pos = static_cast<std::size_t>(it - s.pair_keys.begin());
  s.pair_keys.insert(it, key);
  s.pair_terms.insert(s.pair_terms.begin() + static_cast<std::ptrdiff_t>(pos),
                      thread_internal::SegmentPairTerm(s, a, b, kc, cp, a0, a1, b0, b1));
  return true;
}

double PairStiffness(const ThreadSolverParams& p) {
  return p.contact_stiffness_n_per_mm * units::kNewtonPerMmToInternal;
}

// ---- Proximity contacts at the start of the step: pairs within (1 + margin factor) contact
// distances at x0.
void AddProximityContacts(const std::vector<ThreadModel>& threads,
                          const std::vector<ThreadRest>& rests, const ThreadSolverParams& p,
                          System* sys) {
  System& s = *sys;
  if (s.segments.empty()) return;
  const double pad = 1.0 + p.contact_margin_factor;
  thread_internal::CandidatePairs(&s, threads, rests, p, s.x0, pad);
  for (const auto& pr : s.kept) {
    const ThreadSegmentRef& sa = s.segments[pr[0]];
    const ThreadSegmentRef& sb = s.segments[pr[1]];
    const Vec3 a0 = s.x0.col(sa.n0), a1 = s.x0.col(sa.n1);
    const Vec3 b0 = s.x0.col(sb.n0), b1 = s.x0.col(sb.n1);
    const SegmentClosest cp = ClosestPointsSegments(a0, a1, b0, b1);
    const double dist = 0.5 * (s.seg_diameter[pr[0]] + s.seg_diameter[pr[1]]);
    if (cp.distance < pad * dist)
      AddPairTerm(&s, PairStiffness(p), pr[0], pr[1], cp, a0, a1, b0, b1);
  }
}

// Continuous detection after a solve: every pair without a contact term whose swept motion
// x0 -> x crosses or comes closer than ccd_close_fraction contact distances gets one, with the
// normal of the last sampled configuration before the segments got closer than the contact
// distance (the side they must stay on). True if any was added.
bool AddSweptContacts(const std::vector<ThreadModel>& threads, const std::vector<ThreadRest>& rests,
                      const ThreadSolverParams& p, const Points& x, System* sys) {
  System& s = *sys;
  bool added = false;
  thread_internal::CandidatePairs(&s, threads, rests, p, x, 1.0);
  for (const auto& pr : s.kept) {
    if (std::binary_search(s.pair_keys.begin(), s.pair_keys.end(), pr)) continue;
    const double dist = 0.5 * (s.seg_diameter[pr[0]] + s.seg_diameter[pr[1]]);
    const SweptSegments sw = thread_internal::Swept(s, pr[0], pr[1], x);
    const SweptResult res = SweptSegmentTest(sw, p.crossing_tolerance_mm, p.ccd_samples);
    if (!res.crosses && res.min_distance >= p.ccd_close_fraction * dist) continue;
    const int n = std::max(1, p.ccd_samples);
    double t_ref = 0;
    for (int k = 0; k <= n; ++k) {
      const double tk = static_cast<double>(k) / n;
      if (res.crosses && tk >= res.time) break;
      const SegmentClosest c = ClosestPointsSegments(sw.a0_start + tk * (sw.a0_end - sw.a0_start),
                                                     sw.a1_start + tk * (sw.a1_end - sw.a1_start),
                                                     sw.b0_start + tk * (sw.b0_end - sw.b0_start),
                                                     sw.b1_start + tk * (sw.b1_end - sw.b1_start));
      if (c.distance < dist) break;
      t_ref = tk;
    }
    const Vec3 a0 = sw.a0_start + t_ref * (sw.a0_end - sw.a0_start);
    const Vec3 a1 = sw.a1_start + t_ref * (sw.a1_end - sw.a1_start);
    const Vec3 b0 = sw.b0_start + t_ref * (sw.b0_end - sw.b0_start);
    const Vec3 b1 = sw.b1_start + t_ref * (sw.b1_end - sw.b1_start);
    const SegmentClosest cp = ClosestPointsSegments(a0, a1, b0, b1);
    added |= AddPairTerm(&s, PairStiffness(p), pr[0], pr[1], cp, a0, a1, b0, b1);
  }
  return added;
}

// ---- Solve, then continuous detection and re-solve. Newton starts from x0, which is on the
// length constraints; the explicit guess x0 + dt v0 of a moving slack chain is not (its
// stretch energy can be 1e5 times the step's), and on the benchmark scene it keeps Newton
// at its iteration cap. The step energy is not convex for a compressed chain, so the start
// can decide which minimum a step finds (an arch draped over another thread is one such case).
void SolveWithContinuousDetection(const std::vector<ThreadModel>& threads,
                                  const std::vector<ThreadRest>& rests, const ThreadSolverParams& p,
                                  System* sys, ThreadStepStats* stats) {
  System& s = *sys;
  s.x = s.x0;
  Points& x = s.x;
  for (int round = 0;; ++round) {
    bool converged = false;
    const int iters = thread_internal::NewtonSolve(&s, p, &x, &converged);
    stats->newton_iterations += iters;
    stats->max_newton_per_solve = std::max(stats->max_newton_per_solve, iters);
    if (!converged) ++stats->unconverged_solves;
    stats->strain_limited_segments +=
        thread_internal::LimitStrain(&s, p.max_strain, p.strain_limit_passes, &x);
    ++stats->solves;
    if (s.segments.empty() || round >= p.max_ccd_rounds) break;
    if (!AddSweptContacts(threads, rests, p, x, &s)) break;
  }
  stats->contact_pairs = static_cast<int>(s.pair_terms.size());
}

// ---- Fail-safe: revert every thread involved in a crossing to its start-of-step position
// (whole threads, so no segment is torn). x0 is crossing-free, so this terminates.
void RevertCrossingThreads(const std::vector<ThreadModel>& threads,
                           const std::vector<ThreadRest>& rests, const ThreadSolverParams& p,
                           System* sys, ThreadStepStats* stats) {
  System& s = *sys;
  if (s.segments.empty()) return;
  const int nt = static_cast<int>(threads.size());
  Points& x = s.x;
  s.frozen.assign(nt, 0);
  thread_internal::CandidatePairs(&s, threads, rests, p, x, 1.0);
  for (int pass = 0; pass <= nt; ++pass) {
    bool any = false;
    for (const auto& pr : s.kept) {
      const SweptResult res =
          SweptSegmentTest(thread_internal::Swept(s, pr[0], pr[1], x), p.crossing_tolerance_mm, 1);
      if (!res.crosses) continue;
      for (int seg : pr) {
        const int t = s.segments[seg].thread;
        if (s.frozen[t]) continue;
        s.frozen[t] = 1;
        any = true;
        for (int i = s.offset[t]; i < ThreadEnd(s, t, nt); ++i) {
          if (s.dof[i] < 0) continue;
          x.col(i) = s.x0.col(i);
          ++stats->frozen_nodes;
        }
      }
    }
    if (!any) break;
  }
}

// ---- Write back: positions, and velocities (x - x0) / dt capped at the thread's max speed.
void WriteBack(const std::vector<ThreadModel>& threads, const System& s,
               std::vector<ThreadState>* states, ThreadStepStats* stats) {
  const Points& x = s.x;
  for (int t = 0; t < static_cast<int>(threads.size()); ++t) {
    ThreadState& st = (*states)[t];
    for (int i = 0; i < st.x.cols(); ++i) {
      const int g = s.offset[t] + i;
      if (!s.alive[g]) continue;
      if (s.dof[g] < 0) {
        st.v.col(i).setZero();
        continue;
      }
      Vec3 v = (x.col(g) - s.x0.col(g)) / s.dt;
      const double vmax = threads[t].max_speed_mm_s, speed = v.norm();
      if (vmax > 0 && speed > vmax) {
        v *= vmax / speed;  // the carried momentum never exceeds the cap
        ++stats->speed_capped_nodes;
      }
      st.v.col(i) = v;
      st.x.col(i) = x.col(g);
    }
  }
}

// Force outputs of the thread contacts (N, magnitude) and springs (N, on the thread) at the
// end-of-step positions.
void FillForceOutputs(const System& s, ContactSet* contacts, SpringSet* springs) {
  const Points& x = s.x;
  Vec3 g;
  if (contacts) {
    for (std::size_t c = 0; c < contacts->size(); ++c) {
      if ((*contacts)[c].target != PointContact::Target::kThread) continue;
      (*contacts)[c].force_n = 0;
      if (s.contact_term[c] < 0) continue;
      const Term& t = s.fixed_terms[s.contact_term[c]];
      thread_internal::TermEval(t, thread_internal::TermY(t, x), &g, nullptr);
      (*contacts)[c].force_n = g.norm() * units::kInternalForceToNewton;
    }
  }
  if (springs) {
    for (std::size_t c = 0; c < springs->size(); ++c) {
      if ((*springs)[c].target != PointContact::Target::kThread) continue;
      (*springs)[c].force_n.setZero();
      if (s.spring_term[c] < 0) continue;
      const Term& t = s.fixed_terms[s.spring_term[c]];
      thread_internal::TermEval(t, thread_internal::TermY(t, x), &g, nullptr);
      (*springs)[c].force_n = -g * units::kInternalForceToNewton;
    }
  }
}

}  // namespace

ThreadRest MakeThreadRest(const ThreadModel& model) {
  const Points& x = model.initial.nodes;
  const int n = static_cast<int>(x.cols());
  if (n < 2) throw std::invalid_argument("thread '" + model.name + "' needs at least 2 nodes");
  if (!model.initial.edges.empty()) {
    bool chain = static_cast<int>(model.initial.edges.size()) == n - 1;
    for (int i = 0; chain && i < n - 1; ++i)
      chain = model.initial.edges[i][0] == i && model.initial.edges[i][1] == i + 1;
    if (!chain)
      throw std::invalid_argument("thread '" + model.name + "' edges must be the chain 0-1-...-n");
  }
  ThreadRest r;
  const double area = 0.25 * units::kPi * model.diameter_mm * model.diameter_mm;
  const double rho = model.density_kg_m3 * units::kKgPerM3ToInternal;
  r.rest_length_mm.resize(n - 1);
  r.arc_mm.assign(n, 0.0);
  r.mass_kg.assign(n, 0.0);
  for (int i = 0; i + 1 < n; ++i) {
    const double len = (x.col(i + 1) - x.col(i)).norm();
    if (!(len > 0))
      throw std::invalid_argument("thread '" + model.name + "' segment " + std::to_string(i) +
                                  " has zero length");
    r.rest_length_mm[i] = len;
    r.arc_mm[i + 1] = r.arc_mm[i] + len;
    r.mass_kg[i] += 0.5 * rho * area * len;
    r.mass_kg[i + 1] += 0.5 * rho * area * len;
  }
  r.fixed.assign(n, 0);
  for (std::int32_t f : model.fixed_nodes) {
    if (f < 0 || f >= n)
      throw std::invalid_argument("thread '" + model.name + "' fixed node " + std::to_string(f) +
                                  " out of range");
    r.fixed[f] = 1;
  }
  return r;
}

void InitThreadWorkspace(const std::vector<ThreadModel>& threads, ThreadWorkspace* ws) {
  ws->rest.clear();
  for (const ThreadModel& t : threads) ws->rest.push_back(MakeThreadRest(t));
  ws->last = ThreadStepStats{};
  // Room for 8 segment-segment candidates/contacts per segment and 16 off-band columns, so
  // that steps after the first do not allocate unless they need more than that.
  std::size_t nodes = 0;
  for (const ThreadModel& t : threads) nodes += static_cast<std::size_t>(t.initial.nodes.cols());
  ThreadScratch& s = ws->scratch;
  const std::size_t pairs = 8 * nodes;
  s.pair_terms.reserve(pairs);
  s.pair_keys.reserve(pairs);
  s.pairs.reserve(pairs);
  s.kept.reserve(pairs);
  s.fixed_terms.reserve(4 * nodes);
  s.switch_active.reserve(2 * nodes + pairs);
  s.switch_dir.reserve(2 * nodes + pairs);
  s.cols_node.reserve(4 * 16);
  s.cols_node_w.reserve(4 * 16);
  s.cols_dir.reserve(16);
  s.cols_v.reserve(16 * 3 * nodes);
  s.cap_s.reserve(16 * 16);
  s.cap_y.reserve(16);
  s.tri_chain.reserve(nodes + 1);
  // Independent groups: at most one per node.
  s.node_group.reserve(nodes);
  s.stretch_group.reserve(nodes);
  s.switch_group.reserve(2 * nodes + pairs);
  for (std::vector<std::uint8_t>* v :
       {&s.group_changed, &s.group_consistent, &s.group_done, &s.group_converged, &s.group_pending})
    v->reserve(nodes);
  for (std::vector<double>* v :
       {&s.group_alpha, &s.group_e0, &s.group_e1, &s.group_slope, &s.group_step_max})
    v->reserve(nodes);
  s.step_kept.reserve(3 * nodes);
  // Adaptive substeps: one saved start per level that may split.
  s.level_x.resize(kMaxThreadSubstepLevels);
  s.level_v.resize(kMaxThreadSubstepLevels);
  for (int level = 0; level < kMaxThreadSubstepLevels; ++level) {
    s.level_x[level].resize(3, static_cast<Eigen::Index>(nodes));
    s.level_v[level].resize(3, static_cast<Eigen::Index>(nodes));
  }
}

namespace {

// One (sub)step of dt_s from the threads' current states: every stage, stats into *stats.
void StepOnce(const std::vector<ThreadModel>& threads, double dt_s, const Vec3& gravity_mm_s2,
              ContactSet* contacts, SpringSet* springs, std::vector<ThreadState>* states,
              ThreadWorkspace* ws, ThreadStepStats* stats) {
  const ThreadSolverParams& p = ws->params;
  System& s = ws->scratch;
  NumberNodes(threads, *states, ws->rest, dt_s, gravity_mm_s2, &s);
  AddInternalTerms(threads, ws->rest, p, &s);
  AddExternalTerms(ws->rest, contacts, springs, &s);
  AddSpeedBarriers(threads, p, &s);
  AddProximityContacts(threads, ws->rest, p, &s);
  SolveWithContinuousDetection(threads, ws->rest, p, &s, stats);
  RevertCrossingThreads(threads, ws->rest, p, &s, stats);
  WriteBack(threads, s, states, stats);
  FillForceOutputs(s, contacts, springs);
}

// Copies every node's position and velocity between the states and level `level`'s buffers
// (global numbering; sizes kept, so no allocation once InitThreadWorkspace reserved them).
void SaveLevel(const std::vector<ThreadState>& states, int level, System* s) {
  Points& x = s->level_x[level];
  Points& v = s->level_v[level];
  int total = 0;
  for (const ThreadState& st : states) total += static_cast<int>(st.x.cols());
  x.resize(3, total);
  v.resize(3, total);
  int g = 0;
  for (const ThreadState& st : states) {
    const int n = static_cast<int>(st.x.cols());
    x.middleCols(g, n) = st.x;
    v.middleCols(g, n) = st.v;
    g += n;
  }
}

void RestoreLevel(const System& s, int level, std::vector<ThreadState>* states) {
  int g = 0;
  for (ThreadState& st : *states) {
    const int n = static_cast<int>(st.x.cols());
    st.x = s.level_x[level].middleCols(g, n);
    st.v = s.level_v[level].middleCols(g, n);
    g += n;
  }
}

// Adaptive substeps: the step of dt_s at substep level `level`; if any of its solves ends
// unconverged and a deeper level is allowed, the threads go back to the step's start and it is
// redone as two steps of dt_s / 2 (the contact planes and spring anchors held as given). Kept
// (sub)steps add their stats into *total; a redone one adds its Newton iterations and its
// solves as discarded.
void StepAdaptive(const std::vector<ThreadModel>& threads, double dt_s, const Vec3& gravity_mm_s2,
                  ContactSet* contacts, SpringSet* springs, std::vector<ThreadState>* states,
                  ThreadWorkspace* ws, int level, ThreadStepStats* total) {
  const bool may_split = level < ws->params.max_substep_levels;
  if (may_split) SaveLevel(*states, level, &ws->scratch);
  ThreadStepStats st;
  StepOnce(threads, dt_s, gravity_mm_s2, contacts, springs, states, ws, &st);
  total->newton_iterations += st.newton_iterations;
  if (may_split && st.unconverged_solves > 0) {
    total->discarded_solves += st.solves;
    RestoreLevel(ws->scratch, level, states);
    for (int half = 0; half < 2; ++half)
      StepAdaptive(threads, 0.5 * dt_s, gravity_mm_s2, contacts, springs, states, ws, level + 1,
                   total);
    return;
  }
  total->solves += st.solves;
  total->unconverged_solves += st.unconverged_solves;
  total->contact_pairs = std::max(total->contact_pairs, st.contact_pairs);
  total->frozen_nodes += st.frozen_nodes;
  total->speed_capped_nodes += st.speed_capped_nodes;
  total->max_newton_per_solve = std::max(total->max_newton_per_solve, st.max_newton_per_solve);
  total->strain_limited_segments += st.strain_limited_segments;
  ++total->substeps;
}

}  // namespace

void StepThreads(const std::vector<ThreadModel>& threads, double dt_s, const Vec3& gravity_mm_s2,
                 ContactSet* contacts, SpringSet* springs, std::vector<ThreadState>* states,
                 ThreadWorkspace* ws) {
  const int nt = static_cast<int>(threads.size());
  if (static_cast<int>(states->size()) != nt || static_cast<int>(ws->rest.size()) != nt)
    throw std::invalid_argument("StepThreads: threads, states and workspace differ in size");
  ws->last = ThreadStepStats{};
  if (nt == 0) return;
  const int levels = ws->params.max_substep_levels;
  if (levels < 0 || levels > kMaxThreadSubstepLevels)
    throw std::invalid_argument("StepThreads: max_substep_levels must be in [0, " +
                                std::to_string(kMaxThreadSubstepLevels) + "]");
  StepAdaptive(threads, dt_s, gravity_mm_s2, contacts, springs, states, ws, 0, &ws->last);
}

double ThreadEnergy(const ThreadModel& model, const ThreadRest& rest, const ThreadState& state,
                    const Vec3& gravity_mm_s2) {
  const int n = static_cast<int>(state.x.cols());
  const double ea = model.stretch_stiffness_n * units::kNewtonToInternalForce;
  const double ei = model.bend_stiffness_n_mm2 * units::kNewtonToInternalForce;
  double e = 0;
  for (int i = 0; i < n; ++i) {
    if (!state.node_alive[i]) continue;
    e += 0.5 * rest.mass_kg[i] * state.v.col(i).squaredNorm() -
         rest.mass_kg[i] * gravity_mm_s2.dot(state.x.col(i));
  }
  for (int i = 0; i + 1 < n; ++i) {
    if (!state.node_alive[i] || !state.node_alive[i + 1]) continue;
    const double ext = (state.x.col(i + 1) - state.x.col(i)).norm() - rest.rest_length_mm[i];
    e += 0.5 * ea / rest.rest_length_mm[i] * ext * ext;
  }
  for (int i = 1; ei > 0 && i + 1 < n; ++i) {
    if (!state.node_alive[i - 1] || !state.node_alive[i] || !state.node_alive[i + 1]) continue;
    const double l0 = rest.rest_length_mm[i - 1], l1 = rest.rest_length_mm[i];
    const Vec3 k =
        (state.x.col(i + 1) - state.x.col(i)) / l1 - (state.x.col(i) - state.x.col(i - 1)) / l0;
    e += 0.5 * ei / (0.5 * (l0 + l1)) * k.squaredNorm();
  }
  return e;
}

double ThreadLength(const ThreadState& state) {
  double len = 0;
  for (int i = 0; i + 1 < state.x.cols(); ++i)
    if (state.node_alive[i] && state.node_alive[i + 1])
      len += (state.x.col(i + 1) - state.x.col(i)).norm();
  return len;
}

}  // namespace arthrosim::physics
