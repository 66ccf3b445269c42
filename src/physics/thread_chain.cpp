#include "arthrosim/physics/thread_chain.h"

#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "arthrosim/core/units.h"
#include "arthrosim/physics/thread_collision.h"
#include "arthrosim/physics/thread_geometry.h"

namespace arthrosim::physics {

namespace {

// A term acts on y = sum_k w_k x_k over up to four nodes (global indices).
//   kPlane:  0.5 k max(0, offset - n.y)^2           (contacts; self contact uses y = p - q)
//   kSpring: 0.5 k (|y - anchor| - length)^2        (segments, point springs, bending with L = 0)
//   kLimit:  0.5 k max(0, |y - anchor| - length)^2  (speed barrier: node within vmax dt of x0)
struct Term {
  enum class Kind : std::uint8_t { kPlane, kSpring, kLimit };
  Kind kind = Kind::kSpring;
  int count = 0;
  std::array<int, 4> node{-1, -1, -1, -1};
  std::array<double, 4> w{0, 0, 0, 0};
  double k = 0;             // mN/mm
  double k_compress = -1;   // spring stiffness when shorter than its length; < 0 = same as k
  Vec3 vec = Vec3::Zero();  // normal (plane) or anchor (spring)
  double scalar = 0;        // offset (plane) or rest length (spring)
};

struct SegmentRef {
  int thread = 0;
  int seg = 0;  // segment index within the thread (nodes seg, seg + 1)
  int n0 = 0;   // global node indices
  int n1 = 0;
};

struct ContactPair {
  int a = 0, b = 0;  // indices into the segment list, a < b
};

// Everything one step needs, in global node numbering (threads concatenated).
struct System {
  int num_nodes = 0;
  std::vector<int> offset;  // first global node of each thread
  Points x0, v0;
  std::vector<int> dof;  // free-node index or -1 (fixed / dead)
  std::vector<std::uint8_t> alive;
  std::vector<double> mass;     // kg
  std::vector<double> inertia;  // m (1 + alpha dt) / dt^2
  std::vector<SegmentRef> segments;
  std::vector<double> seg_diameter;
  std::vector<Term> fixed_terms;              // stretch, bending, external contacts, springs
  std::vector<Term> pair_terms;               // segment-segment contacts
  std::vector<std::array<int, 2>> pair_keys;  // segment pairs that own a pair term (sorted)
  int num_free = 0;
  double dt = 0;
  Vec3 gravity = Vec3::Zero();
};

Vec3 TermY(const Term& t, const Points& x) {
  Vec3 y = Vec3::Zero();
  for (int k = 0; k < t.count; ++k) y += t.w[k] * x.col(t.node[k]);
  return y;
}

// Energy, gradient wrt y, and the positive semi-definite Hessian wrt y of one term.
double TermEval(const Term& t, const Vec3& y, Vec3* g, Mat3* h) {
  if (t.kind == Term::Kind::kPlane) {
    const double pen = t.scalar - t.vec.dot(y);
    if (pen <= 0) {
      if (g) g->setZero();
      if (h) h->setZero();
      return 0;
    }
    if (g) *g = -t.k * pen * t.vec;
    if (h) *h = t.k * t.vec * t.vec.transpose();
    return 0.5 * t.k * pen * pen;
  }
  const Vec3 d = y - t.vec;
  if (t.scalar == 0) {
    if (g) *g = t.k * d;
    if (h) *h = t.k * Mat3::Identity();
    return 0.5 * t.k * d.squaredNorm();
  }
  const double l = d.norm();
  const double ext = l - t.scalar;
  if (t.kind == Term::Kind::kLimit && ext <= 0) {
    if (g) g->setZero();
    if (h) h->setZero();
    return 0;
  }
  if (l < 1e-12) {
    if (g) g->setZero();
    if (h) *h = t.k * Mat3::Identity();
    return 0.5 * t.k * ext * ext;
  }
  const Vec3 u = d / l;
  const double k = (ext < 0 && t.k_compress >= 0) ? t.k_compress : t.k;
  if (g) *g = k * ext * u;
  if (h) {
    const Mat3 uu = u * u.transpose();
    *h = k * (uu + std::max(0.0, 1.0 - t.scalar / l) * (Mat3::Identity() - uu));
  }
  return 0.5 * k * ext * ext;
}

using Triplet = Eigen::Triplet<double>;

// Residual and Jacobian of the KKT system in (free dofs, stretch multipliers):
//   r_x = M~ (x - x0) - M (v0 / dt + g) + grad U_terms + sum_j lambda_j grad c_j
//   r_j = c_j(x) - lambda_j / k_j
//   K   = [ H + sum_j max(lambda_j, 0) hess c_j    J^T ]
//         [ J                                    -1/k ]
// H is positive definite (masses), the compliance block negative: the matrix is
// quasi-definite, so LDL^T exists without pivoting for any ordering.
double TotalEnergy(const System& s, const Points& x) {
  double e = 0;
  for (int i = 0; i < s.num_nodes; ++i) {
    if (s.dof[i] < 0) continue;
    const Vec3 dx = x.col(i) - s.x0.col(i);
    e += 0.5 * s.inertia[i] * dx.squaredNorm() -
         s.mass[i] * (dx.dot(s.v0.col(i)) / s.dt + dx.dot(s.gravity));
  }
  for (const std::vector<Term>* list : {&s.fixed_terms, &s.pair_terms})
    for (const Term& t : *list) e += TermEval(t, TermY(t, x), nullptr, nullptr);
  return e;
}

void Assemble(const System& s, const Points& x, Eigen::VectorXd* grad, std::vector<Triplet>* trip) {
  grad->setZero(3 * s.num_free);
  trip->clear();
  for (int i = 0; i < s.num_nodes; ++i) {
    const int d = s.dof[i];
    if (d < 0) continue;
    const Vec3 dx = x.col(i) - s.x0.col(i);
    grad->segment<3>(3 * d) += s.inertia[i] * dx - s.mass[i] * (s.v0.col(i) / s.dt + s.gravity);
    for (int c = 0; c < 3; ++c) trip->emplace_back(3 * d + c, 3 * d + c, s.inertia[i]);
  }
  Vec3 g;
  Mat3 h;
  for (const std::vector<Term>* list : {&s.fixed_terms, &s.pair_terms}) {
    for (const Term& t : *list) {
      TermEval(t, TermY(t, x), &g, &h);
      if (h.isZero(0)) continue;
      for (int a = 0; a < t.count; ++a) {
        const int da = s.dof[t.node[a]];
        if (da < 0) continue;
        grad->segment<3>(3 * da) += t.w[a] * g;
        for (int b = 0; b < t.count; ++b) {
          const int db = s.dof[t.node[b]];
          if (db < 0) continue;
          const double wab = t.w[a] * t.w[b];
          for (int r = 0; r < 3; ++r)
            for (int c = 0; c < 3; ++c)
              if (h(r, c) != 0) trip->emplace_back(3 * da + r, 3 * db + c, wab * h(r, c));
        }
      }
    }
  }
}

// Newton with a backtracking (Armijo) line search on the incremental potential, from *x.
// Every accepted iterate lowers the energy, so a step that is cut short by the iteration limit
// is still stable. Returns the number of iterations.
int NewtonSolve(const System& s, const ThreadSolverParams& p, Points* x) {
  if (s.num_free == 0) return 0;
  Eigen::VectorXd grad;
  std::vector<Triplet> trip;
  Eigen::SparseMatrix<double> hess(3 * s.num_free, 3 * s.num_free);
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt;
  Points trial = *x;
  double e0 = TotalEnergy(s, *x);
  int it = 0;
  while (it < p.max_newton_iterations) {
    ++it;
    Assemble(s, *x, &grad, &trip);
    hess.setFromTriplets(trip.begin(), trip.end());
    // The pattern changes with contact activity, so order and factorise every iteration (the
    // systems are a few hundred unknowns; this is not the cost that matters).
    ldlt.compute(hess);
    if (ldlt.info() != Eigen::Success) break;
    const Eigen::VectorXd step = ldlt.solve(-grad);
    if (!step.allFinite()) break;
    const double step_max = step.cwiseAbs().maxCoeff();
    const double slope = grad.dot(step);
    double alpha = 1.0;
    bool accepted = false;
    double e1 = e0;
    for (int ls = 0; ls < 30; ++ls) {
      trial = *x;
      for (int i = 0; i < s.num_nodes; ++i)
        if (s.dof[i] >= 0) trial.col(i) += alpha * step.segment<3>(3 * s.dof[i]);
      e1 = TotalEnergy(s, trial);
      if (e1 <= e0 + 1e-4 * alpha * slope) {
        accepted = true;
        break;
      }
      alpha *= 0.5;
    }
    if (!accepted) break;  // rounding floor: the energy cannot resolve the step any more
    *x = trial;
    e0 = e1;
    if (alpha * step_max < p.newton_tolerance_mm) break;
  }
  return it;
}

// Adds a point term built from (thread, nodes, weights); false if it touches a dead node.
bool PointTerm(const System& s, int thread, const std::array<std::int32_t, 4>& nodes,
               const std::array<double, 4>& weights, int thread_nodes, Term* t) {
  t->count = 0;
  for (int k = 0; k < 4; ++k) {
    if (nodes[k] < 0 || weights[k] == 0) continue;
    if (nodes[k] >= thread_nodes)
      throw std::invalid_argument("thread contact/spring node " + std::to_string(nodes[k]) +
                                  " out of range");
    const int g = s.offset[thread] + nodes[k];
    if (!s.alive[g]) return false;
    t->node[t->count] = g;
    t->w[t->count] = weights[k];
    ++t->count;
  }
  return t->count > 0;
}

Term SegmentPairTerm(const System& s, int a, int b, const Points& x, double stiffness,
                     const SegmentClosest& cp) {
  const SegmentRef& sa = s.segments[a];
  const SegmentRef& sb = s.segments[b];
  Term t;
  t.kind = Term::Kind::kPlane;
  t.count = 4;
  t.node = {sa.n0, sa.n1, sb.n0, sb.n1};
  t.w = {1 - cp.s, cp.s, -(1 - cp.t), -cp.t};
  t.k = stiffness;
  Vec3 n = cp.p - cp.q;
  const double len = n.norm();
  if (len > 1e-12) {
    n /= len;
  } else {
    // Touching exactly: separate along the common perpendicular (or any perpendicular).
    const Vec3 da = x.col(sa.n1) - x.col(sa.n0), db = x.col(sb.n1) - x.col(sb.n0);
    n = da.cross(db);
    if (n.norm() < 1e-12) n = da.unitOrthogonal();
    n.normalize();
  }
  t.vec = n;
  t.scalar = 0.5 * (s.seg_diameter[a] + s.seg_diameter[b]);
  return t;
}

bool PairExcluded(const System& s, const std::vector<ThreadModel>& models,
                  const std::vector<ThreadRest>& rest, double exclusion_factor, int a, int b) {
  const SegmentRef& sa = s.segments[a];
  const SegmentRef& sb = s.segments[b];
  if (sa.thread != sb.thread) return false;
  if (!models[sa.thread].self_collision) return true;
  const int i = std::min(sa.seg, sb.seg), j = std::max(sa.seg, sb.seg);
  if (j - i < 2) return true;
  const double gap = rest[sa.thread].arc_mm[j] - rest[sa.thread].arc_mm[i + 1];
  return gap < exclusion_factor * models[sa.thread].diameter_mm;
}

SweptSegments Swept(const System& s, int a, int b, const Points& x1) {
  const SegmentRef& sa = s.segments[a];
  const SegmentRef& sb = s.segments[b];
  return SweptSegments{s.x0.col(sa.n0), s.x0.col(sa.n1), s.x0.col(sb.n0), s.x0.col(sb.n1),
                       x1.col(sa.n0),   x1.col(sa.n1),   x1.col(sb.n0),   x1.col(sb.n1)};
}

std::vector<std::array<int, 2>> CandidatePairs(const System& s,
                                               const std::vector<ThreadModel>& models,
                                               const std::vector<ThreadRest>& rest,
                                               const ThreadSolverParams& p, const Points& x1,
                                               double pad_factor) {
  std::vector<Box3> boxes(s.segments.size());
  for (std::size_t i = 0; i < s.segments.size(); ++i) {
    const SegmentRef& sg = s.segments[i];
    boxes[i] = SweptSegmentBox(s.x0.col(sg.n0), s.x0.col(sg.n1), x1.col(sg.n0), x1.col(sg.n1),
                               0.5 * s.seg_diameter[i] * pad_factor);
  }
  std::vector<std::array<int, 2>> pairs = OverlappingPairs(boxes);
  std::vector<std::array<int, 2>> kept;
  kept.reserve(pairs.size());
  for (const auto& pr : pairs)
    if (!PairExcluded(s, models, rest, p.exclusion_factor, pr[0], pr[1])) kept.push_back(pr);
  return kept;
}

// Strain limiting (Provot 1995): Newton on a slack, nearly inextensible chain converges slowly,
// so an unconverged iterate may be over-stretched. A few Gauss-Seidel passes (in segment order,
// deterministic) shorten every segment longer than (1 + max_strain) L0, moving its ends in
// inverse proportion to their masses (fixed nodes do not move).
void LimitStrain(const System& s, double max_strain, int passes, Points* x) {
  for (int pass = 0; pass < passes; ++pass) {
    bool changed = false;
    for (const Term& t : s.fixed_terms) {
      if (t.kind != Term::Kind::kSpring || t.k_compress < 0) continue;  // stretch terms only
      const int a = t.node[0], b = t.node[1];
      const double wa = s.dof[a] >= 0 ? 1.0 / s.mass[a] : 0.0;
      const double wb = s.dof[b] >= 0 ? 1.0 / s.mass[b] : 0.0;
      if (wa + wb == 0) continue;
      const Vec3 e = x->col(b) - x->col(a);
      const double l = e.norm(), lmax = (1 + max_strain) * t.scalar;
      if (l <= lmax) continue;
      const Vec3 corr = (l - lmax) / (l * (wa + wb)) * e;
      x->col(a) += wa * corr;
      x->col(b) -= wb * corr;
      changed = true;
    }
    if (!changed) break;
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
}

void StepThreads(const std::vector<ThreadModel>& threads, double dt_s, const Vec3& gravity_mm_s2,
                 ContactSet* contacts, SpringSet* springs, std::vector<ThreadState>* states,
                 ThreadWorkspace* ws) {
  const ThreadSolverParams& p = ws->params;
  const int nt = static_cast<int>(threads.size());
  if (static_cast<int>(states->size()) != nt || static_cast<int>(ws->rest.size()) != nt)
    throw std::invalid_argument("StepThreads: threads, states and workspace differ in size");
  ws->last = ThreadStepStats{};
  if (nt == 0) return;

  // ---- Global numbering.
  System s;
  s.dt = dt_s;
  s.gravity = gravity_mm_s2;
  s.offset.resize(nt);
  for (int t = 0; t < nt; ++t) {
    s.offset[t] = s.num_nodes;
    s.num_nodes += static_cast<int>((*states)[t].x.cols());
  }
  s.x0.resize(3, s.num_nodes);
  s.v0.resize(3, s.num_nodes);
  s.dof.assign(s.num_nodes, -1);
  s.alive.assign(s.num_nodes, 0);
  s.mass.assign(s.num_nodes, 0.0);
  s.inertia.assign(s.num_nodes, 0.0);
  for (int t = 0; t < nt; ++t) {
    const ThreadState& st = (*states)[t];
    const ThreadRest& r = ws->rest[t];
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
    }
  }

  // ---- Internal terms: stretch and bending.
  for (int t = 0; t < nt; ++t) {
    const ThreadModel& m = threads[t];
    const ThreadRest& r = ws->rest[t];
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
      s.fixed_terms.push_back(term);
      s.segments.push_back(SegmentRef{t, i, g0, g1});
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

  // ---- External contacts and springs (targets kThread only).
  std::vector<int> contact_term(contacts ? contacts->size() : 0, -1);
  std::vector<int> spring_term(springs ? springs->size() : 0, -1);
  if (contacts) {
    for (std::size_t c = 0; c < contacts->size(); ++c) {
      const PointContact& pc = (*contacts)[c];
      if (pc.target != PointContact::Target::kThread) continue;
      if (pc.index < 0 || pc.index >= nt)
        throw std::invalid_argument("PointContact thread index out of range");
      Term term;
      term.kind = Term::Kind::kPlane;
      if (!PointTerm(s, pc.index, pc.nodes, pc.weights,
                     static_cast<int>(ws->rest[pc.index].mass_kg.size()), &term))
        continue;
      term.k = pc.stiffness_n_per_mm * units::kNewtonPerMmToInternal;
      term.vec = pc.normal;
      term.scalar = pc.offset_mm;
      contact_term[c] = static_cast<int>(s.fixed_terms.size());
      s.fixed_terms.push_back(term);
    }
  }
  if (springs) {
    for (std::size_t c = 0; c < springs->size(); ++c) {
      const PointSpring& ps = (*springs)[c];
      if (ps.target != PointContact::Target::kThread) continue;
      if (ps.index < 0 || ps.index >= nt)
        throw std::invalid_argument("PointSpring thread index out of range");
      Term term;
      term.kind = Term::Kind::kSpring;
      if (!PointTerm(s, ps.index, ps.nodes, ps.weights,
                     static_cast<int>(ws->rest[ps.index].mass_kg.size()), &term))
        continue;
      term.k = ps.stiffness_n_per_mm * units::kNewtonPerMmToInternal;
      term.vec = ps.anchor_mm;
      term.scalar = ps.rest_length_mm;
      spring_term[c] = static_cast<int>(s.fixed_terms.size());
      s.fixed_terms.push_back(term);
    }
  }

  // ---- Speed barrier: each free node stays within vmax dt of its start (paper's anti-jitter
  // limit), inside the solve so that the chain keeps its length while it is slowed down.
  for (int t = 0; t < nt; ++t) {
    const double vmax = threads[t].max_speed_mm_s;
    if (!(vmax > 0)) continue;
    const int end = t + 1 < nt ? s.offset[t + 1] : s.num_nodes;
    for (int i = s.offset[t]; i < end; ++i) {
      if (s.dof[i] < 0) continue;
      Term term;
      term.kind = Term::Kind::kLimit;
      term.count = 1;
      term.node = {i, -1, -1, -1};
      term.w = {1, 0, 0, 0};
      term.k = p.speed_barrier_stiffness_n_per_mm * units::kNewtonPerMmToInternal;
      term.vec = s.x0.col(i);
      term.scalar = vmax * dt_s;
      s.fixed_terms.push_back(term);
    }
  }

  // ---- Proximity contacts at the start of the step.
  const double kc = p.contact_stiffness_n_per_mm * units::kNewtonPerMmToInternal;
  auto add_pair = [&](int a, int b, const SegmentClosest& cp, const Points& xref) {
    const std::array<int, 2> key{a, b};
    auto it = std::lower_bound(s.pair_keys.begin(), s.pair_keys.end(), key);
    if (it != s.pair_keys.end() && *it == key) return false;
    const std::size_t pos = static_cast<std::size_t>(it - s.pair_keys.begin());
    s.pair_keys.insert(it, key);
    s.pair_terms.insert(s.pair_terms.begin() + static_cast<std::ptrdiff_t>(pos),
                        SegmentPairTerm(s, a, b, xref, kc, cp));
    return true;
  };
  if (!s.segments.empty()) {
    const double pad = 1.0 + p.contact_margin_factor;
    for (const auto& pr : CandidatePairs(s, threads, ws->rest, p, s.x0, pad)) {
      const SegmentRef& sa = s.segments[pr[0]];
      const SegmentRef& sb = s.segments[pr[1]];
      const SegmentClosest cp =
          ClosestPointsSegments(s.x0.col(sa.n0), s.x0.col(sa.n1), s.x0.col(sb.n0), s.x0.col(sb.n1));
      const double dist = 0.5 * (s.seg_diameter[pr[0]] + s.seg_diameter[pr[1]]);
      if (cp.distance < pad * dist) add_pair(pr[0], pr[1], cp, s.x0);
    }
  }

  // ---- Solve, then continuous detection and re-solve.
  Points x = s.x0;
  for (int i = 0; i < s.num_nodes; ++i)
    if (s.dof[i] >= 0) x.col(i) += dt_s * s.v0.col(i);
  for (int round = 0;; ++round) {
    ws->last.newton_iterations += NewtonSolve(s, p, &x);
    LimitStrain(s, p.max_strain, p.strain_limit_passes, &x);
    ++ws->last.solves;
    if (s.segments.empty() || round >= p.max_ccd_rounds) break;
    bool added = false;
    for (const auto& pr : CandidatePairs(s, threads, ws->rest, p, x, 1.0)) {
      if (std::binary_search(s.pair_keys.begin(), s.pair_keys.end(), pr)) continue;
      const double dist = 0.5 * (s.seg_diameter[pr[0]] + s.seg_diameter[pr[1]]);
      const SweptSegments sw = Swept(s, pr[0], pr[1], x);
      const SweptResult res = SweptSegmentTest(sw, p.crossing_tolerance_mm, p.ccd_samples);
      if (!res.crosses && res.min_distance >= p.ccd_close_fraction * dist) continue;
      // Normal from the last sampled configuration before the segments got closer than the
      // contact distance: the side they must stay on.
      const int n = std::max(1, p.ccd_samples);
      double t_ref = 0;
      for (int k = 0; k <= n; ++k) {
        const double tk = static_cast<double>(k) / n;
        if (res.crosses && tk >= res.time) break;
        const SegmentClosest c =
            ClosestPointsSegments(sw.a0_start + tk * (sw.a0_end - sw.a0_start),
                                  sw.a1_start + tk * (sw.a1_end - sw.a1_start),
                                  sw.b0_start + tk * (sw.b0_end - sw.b0_start),
                                  sw.b1_start + tk * (sw.b1_end - sw.b1_start));
        if (c.distance < dist) break;
        t_ref = tk;
      }
      const Points xref = s.x0 + t_ref * (x - s.x0);
      const SegmentRef& sa = s.segments[pr[0]];
      const SegmentRef& sb = s.segments[pr[1]];
      const SegmentClosest cp =
          ClosestPointsSegments(xref.col(sa.n0), xref.col(sa.n1), xref.col(sb.n0), xref.col(sb.n1));
      added |= add_pair(pr[0], pr[1], cp, xref);
    }
    if (!added) break;
  }
  ws->last.contact_pairs = static_cast<int>(s.pair_terms.size());

  // ---- Fail-safe: revert every thread involved in a crossing to its start-of-step position
  // (whole threads, so no segment is torn). x0 is crossing-free, so this terminates.
  if (!s.segments.empty()) {
    std::vector<std::uint8_t> frozen(nt, 0);
    const std::vector<std::array<int, 2>> cand = CandidatePairs(s, threads, ws->rest, p, x, 1.0);
    for (int pass = 0; pass <= nt; ++pass) {
      bool any = false;
      for (const auto& pr : cand) {
        const SweptResult res =
            SweptSegmentTest(Swept(s, pr[0], pr[1], x), p.crossing_tolerance_mm, 1);
        if (!res.crosses) continue;
        for (int seg : pr) {
          const int t = s.segments[seg].thread;
          if (frozen[t]) continue;
          frozen[t] = 1;
          any = true;
          const int end = t + 1 < nt ? s.offset[t + 1] : s.num_nodes;
          for (int i = s.offset[t]; i < end; ++i) {
            if (s.dof[i] < 0) continue;
            x.col(i) = s.x0.col(i);
            ++ws->last.frozen_nodes;
          }
        }
      }
      if (!any) break;
    }
  }

  // ---- Write back.
  for (int t = 0; t < nt; ++t) {
    ThreadState& st = (*states)[t];
    for (int i = 0; i < st.x.cols(); ++i) {
      const int g = s.offset[t] + i;
      if (!s.alive[g]) continue;
      if (s.dof[g] < 0) {
        st.v.col(i).setZero();
        continue;
      }
      Vec3 v = (x.col(g) - s.x0.col(g)) / dt_s;
      const double vmax = threads[t].max_speed_mm_s, speed = v.norm();
      if (vmax > 0 && speed > vmax) {
        v *= vmax / speed;  // the carried momentum never exceeds the cap
        ++ws->last.speed_capped_nodes;
      }
      st.v.col(i) = v;
      st.x.col(i) = x.col(g);
    }
  }
  Vec3 g;
  if (contacts) {
    for (std::size_t c = 0; c < contacts->size(); ++c) {
      if ((*contacts)[c].target != PointContact::Target::kThread) continue;
      (*contacts)[c].force_n = 0;
      if (contact_term[c] < 0) continue;
      const Term& t = s.fixed_terms[contact_term[c]];
      TermEval(t, TermY(t, x), &g, nullptr);
      (*contacts)[c].force_n = g.norm() * units::kInternalForceToNewton;
    }
  }
  if (springs) {
    for (std::size_t c = 0; c < springs->size(); ++c) {
      if ((*springs)[c].target != PointContact::Target::kThread) continue;
      (*springs)[c].force_n.setZero();
      if (spring_term[c] < 0) continue;
      const Term& t = s.fixed_terms[spring_term[c]];
      TermEval(t, TermY(t, x), &g, nullptr);
      (*springs)[c].force_n = -g * units::kInternalForceToNewton;
    }
  }
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
