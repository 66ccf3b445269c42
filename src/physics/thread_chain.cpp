#include "arthrosim/physics/thread_chain.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "arthrosim/core/units.h"
#include "arthrosim/physics/thread_collision.h"
#include "arthrosim/physics/thread_geometry.h"

namespace arthrosim::physics {

namespace {

using Term = ThreadTerm;
using System = ThreadScratch;

[[gnu::always_inline]] inline Vec3 TermY(const Term& t, const Points& x) {
  Vec3 y = Vec3::Zero();
  for (int k = 0; k < t.count; ++k) y += t.w[k] * x.col(t.node[k]);
  return y;
}

// Energy, gradient wrt y, and the positive semi-definite Hessian wrt y of one term.
[[gnu::always_inline]] inline double TermEval(const Term& t, const Vec3& y, Vec3* g, Mat3* h) {
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

// Stretch energy 0.5 k(c) c^2 of segment j, c = l - L (stiffness k_compress when c < 0).
double StretchEnergy(const Term& t, const Points& x) {
  const double c = (x.col(t.node[1]) - x.col(t.node[0])).norm() - t.scalar;
  return 0.5 * (c < 0 ? t.k_compress : t.k) * c * c;
}

double TotalEnergy(const System& s, const Points& x) {
  double e = 0;
  for (int i = 0; i < s.num_nodes; ++i) {
    if (s.dof[i] < 0) continue;
    const Vec3 dx = x.col(i) - s.x0.col(i);
    e += 0.5 * s.inertia[i] * dx.squaredNorm() -
         s.mass[i] * (dx.dot(s.v0.col(i)) / s.dt + dx.dot(s.gravity));
  }
  for (const Term& t : s.stretch_terms) e += StretchEnergy(t, x);
  for (const std::vector<Term>* list : {&s.fixed_terms, &s.pair_terms})
    for (const Term& t : *list) e += TermEval(t, TermY(t, x), nullptr, nullptr);
  return e;
}

// ---- Newton matrix: banded part (inertia, stretch, bending, point contacts and springs on
// neighbouring nodes) plus off-band rank-1 columns (segment-segment contacts), solved with the
// banded LDL^T and a Woodbury capacitance matrix.

void AddColumn(System* s, const Term& t, const Vec3& dir) {
  for (int k = 0; k < 4; ++k) {
    s->cols_node.push_back(k < t.count ? t.node[k] : -1);
    s->cols_node_w.push_back(k < t.count ? t.w[k] : 0.0);
  }
  s->cols_dir.push_back(dir);
}

// Adds the Hessian h (wrt y) of term t to the band, or as columns if it spans more than the band.
void AddTermHessian(System* s, const Term& t, const Mat3& h) {
  int lo = t.node[0], hi = t.node[0];
  for (int k = 1; k < t.count; ++k) {
    lo = std::min(lo, t.node[k]);
    hi = std::max(hi, t.node[k]);
  }
  if (hi - lo <= 2) {
    for (int a = 0; a < t.count; ++a) {
      if (s->dof[t.node[a]] < 0) continue;
      for (int b = 0; b < t.count; ++b) {
        if (s->dof[t.node[b]] < 0 || t.node[a] < t.node[b]) continue;
        const Mat3 hab = (t.w[a] * t.w[b]) * h;
        const int row = t.node[a], col = t.node[b];  // row >= col: AddBandedBlock inlined
        if (row == col)
          s->band.diag[row] += hab;
        else if (row == col + 1)
          s->band.sub1[col] += hab;
        else
          s->band.sub2[col] += hab;
      }
    }
    return;
  }
  // Off-band: h = sum_i e_i v_i v_i^T with e_i >= 0 (h is symmetric positive semi-definite).
  if (t.kind == Term::Kind::kPlane) {
    AddColumn(s, t, std::sqrt(t.k) * t.vec);
    return;
  }
  Eigen::SelfAdjointEigenSolver<Mat3> eig(h);
  for (int i = 0; i < 3; ++i)
    if (eig.eigenvalues()(i) > 0)
      AddColumn(s, t, std::sqrt(eig.eigenvalues()(i)) * eig.eigenvectors().col(i));
}

// u_c^T v for column c and a 3 n vector v.
double ColumnDot(const System& s, int c, const double* v) {
  double r = 0;
  for (int k = 0; k < 4; ++k) {
    const int node = s.cols_node[4 * c + k];
    if (node < 0 || s.dof[node] < 0) continue;
    r += s.cols_node_w[4 * c + k] * s.cols_dir[c].dot(Eigen::Map<const Vec3>(v + 3 * node));
  }
  return r;
}

// Solves (B + U U^T) step = rhs, B factored in s->band; U = the off-band columns.
void SolveWithColumns(System* s) {
  const int n3 = 3 * s->num_nodes;
  SolveBanded(s->band, s->rhs.data(), s->step.data());
  const int m = static_cast<int>(s->cols_dir.size());
  if (m == 0) return;
  s->cols_v.assign(static_cast<std::size_t>(m) * n3, 0.0);
  for (int c = 0; c < m; ++c) {
    double* v = s->cols_v.data() + static_cast<std::size_t>(c) * n3;
    for (int k = 0; k < 4; ++k) {
      const int node = s->cols_node[4 * c + k];
      if (node < 0 || s->dof[node] < 0) continue;
      Eigen::Map<Vec3>(v + 3 * node) += s->cols_node_w[4 * c + k] * s->cols_dir[c];
    }
    SolveBanded(s->band, v, v);
  }
  // Capacitance S = I + U^T B^-1 U (symmetric positive definite), dense Cholesky in place.
  s->cap_s.assign(static_cast<std::size_t>(m) * m, 0.0);
  s->cap_y.assign(m, 0.0);
  double* S = s->cap_s.data();
  for (int a = 0; a < m; ++a) {
    for (int b = 0; b <= a; ++b) {
      S[a * m + b] = ColumnDot(*s, a, s->cols_v.data() + static_cast<std::size_t>(b) * n3);
      if (a == b) S[a * m + b] += 1.0;
    }
    s->cap_y[a] = ColumnDot(*s, a, s->step.data());
  }
  for (int j = 0; j < m; ++j) {
    double d = S[j * m + j];
    for (int k = 0; k < j; ++k) d -= S[j * m + k] * S[j * m + k];
    d = std::sqrt(std::max(d, 1e-300));
    S[j * m + j] = d;
    for (int i = j + 1; i < m; ++i) {
      double v = S[i * m + j];
      for (int k = 0; k < j; ++k) v -= S[i * m + k] * S[j * m + k];
      S[i * m + j] = v / d;
    }
  }
  double* y = s->cap_y.data();
  for (int i = 0; i < m; ++i) {
    for (int k = 0; k < i; ++k) y[i] -= S[i * m + k] * y[k];
    y[i] /= S[i * m + i];
  }
  for (int i = m - 1; i >= 0; --i) {
    for (int k = i + 1; k < m; ++k) y[i] -= S[k * m + i] * y[k];
    y[i] /= S[i * m + i];
  }
  for (int c = 0; c < m; ++c) {
    const double* v = s->cols_v.data() + static_cast<std::size_t>(c) * n3;
    for (int i = 0; i < n3; ++i) s->step[i] -= y[c] * v[i];
  }
}

// Builds the part of the Newton system at x that does not depend on the predicted activity of
// the switching terms (inertia, stretch, bending and point springs) into s->band_base and the
// spring columns, the true gradient of the energy at x into s->grad (independent of the
// activity model), and y, gradient and Hessian of every switching term into s->sw_*. The
// active-set passes of one Newton iteration share it. Stretch terms use the multipliers
// s->lambda for their transverse (geometric) stiffness: lambda / l (I - u u^T), the Hessian of
// the Lagrangian of the stretch constraints (SQP), which stays right when a Newton step rotates
// a segment, where the primal k (1 - L / l) explodes. With allow_negative, compressed segments
// keep their negative geometric term (exact Hessian; a slack chain then converges
// quadratically instead of linearly); the caller rebuilds without it if the factorisation finds
// the matrix indefinite.
void BuildBase(System* s, const Points& x, bool allow_negative) {
  const int n = s->num_nodes;
  BandedBlockMatrix& band = s->band;  // assembled here, then kept in band_base
  ResetBanded(n, &band);
  s->grad.assign(3 * n, 0.0);
  s->cols_node.clear();
  s->cols_node_w.clear();
  s->cols_dir.clear();
  for (int i = 0; i < n; ++i) {
    if (s->dof[i] < 0) {
      band.diag[i] = Mat3::Identity();
      continue;
    }
    const Vec3 dx = x.col(i) - s->x0.col(i);
    const Vec3 g = s->inertia[i] * dx - s->mass[i] * (s->v0.col(i) / s->dt + s->gravity);
    Eigen::Map<Vec3>(s->grad.data() + 3 * i) += g;
    band.diag[i] += s->inertia[i] * Mat3::Identity();
  }
  auto add_grad = [&](const Term& t, const Vec3& g) {
    for (int a = 0; a < t.count; ++a)
      if (s->dof[t.node[a]] >= 0) Eigen::Map<Vec3>(s->grad.data() + 3 * t.node[a]) += t.w[a] * g;
  };
  for (std::size_t j = 0; j < s->stretch_terms.size(); ++j) {
    const Term& t = s->stretch_terms[j];
    const int n0 = t.node[0], n1 = t.node[1];  // weights -1, +1; n1 = n0 + 1
    const Vec3 e = x.col(n1) - x.col(n0);
    const double l = std::max(e.norm(), 1e-12);
    const Vec3 u = e / l;
    const double c = l - t.scalar;
    const double k = c < 0 ? t.k_compress : t.k;
    const Vec3 g = k * c * u;
    add_grad(t, g);
    const double lam = allow_negative ? s->lambda[j] : std::max(0.0, s->lambda[j]);
    const Mat3 uu = u * u.transpose();
    const Mat3 h = k * uu + (lam / l) * (Mat3::Identity() - uu);
    // The blocks of AddTermHessian for weights (-1, +1), in its order.
    const bool f0 = s->dof[n0] >= 0, f1 = s->dof[n1] >= 0;
    if (f0) band.diag[n0] += h;
    if (f1) {
      if (f0) band.sub1[n0] -= h;
      band.diag[n1] += h;
    }
  }
  s->sw_y.clear();
  s->sw_g.clear();
  s->sw_h.clear();
  Vec3 g;
  Mat3 h;
  for (const std::vector<Term>* list : {&s->fixed_terms, &s->pair_terms}) {
    for (const Term& t : *list) {
      const Vec3 y = TermY(t, x);
      TermEval(t, y, &g, &h);
      add_grad(t, g);
      if (t.kind == Term::Kind::kSpring) {
        if (!h.isZero(0)) AddTermHessian(s, t, h);
        continue;
      }
      s->sw_y.push_back(y);
      s->sw_g.push_back(g);
      s->sw_h.push_back(h);
    }
  }
  s->base_cols = static_cast<int>(s->cols_dir.size());
  std::swap(s->band, s->band_base);
}

// Completes the Newton system from s->band_base with the switching terms (contact planes and
// speed barriers) at their activity s->switch_active, factors it and solves it into s->step.
// Returns false if the matrix is not positive definite or the step is not finite.
bool SolveModel(System* s) {
  const int n = s->num_nodes;
  s->band.n = s->band_base.n;  // copies keep their capacity: no allocation
  s->band.diag = s->band_base.diag;
  s->band.sub1 = s->band_base.sub1;
  s->band.sub2 = s->band_base.sub2;
  s->cols_node.resize(4 * s->base_cols);
  s->cols_node_w.resize(4 * s->base_cols);
  s->cols_dir.resize(s->base_cols);
  s->rhs.assign(3 * n, 0.0);
  s->step.resize(3 * n);
  auto add_rhs = [&](const Term& t, const Vec3& g) {
    for (int a = 0; a < t.count; ++a)
      if (s->dof[t.node[a]] >= 0) Eigen::Map<Vec3>(s->rhs.data() + 3 * t.node[a]) += t.w[a] * g;
  };
  int sw = 0;
  for (const std::vector<Term>* list : {&s->fixed_terms, &s->pair_terms}) {
    for (const Term& t : *list) {
      if (t.kind == Term::Kind::kSpring) continue;
      // Switching term: the model uses its predicted activity; rhs collects model - true
      // gradient.
      const int a = sw++;
      const Vec3& y = s->sw_y[a];
      const Vec3& g = s->sw_g[a];
      const Mat3& h = s->sw_h[a];
      if (!s->switch_active[a]) {
        if (!g.isZero(0)) add_rhs(t, -g);  // most candidate pairs are apart: nothing to add
        continue;
      }
      if (t.kind == Term::Kind::kPlane) {
        // Exact piecewise-quadratic model k (offset - n.y), also when y is outside now.
        const double pen = t.scalar - t.vec.dot(y);
        add_rhs(t, -t.k * pen * t.vec - g);
        AddTermHessian(s, t, t.k * t.vec * t.vec.transpose());
      } else if (!h.isZero(0)) {
        AddTermHessian(s, t, h);  // speed barrier active now: its own Hessian
      } else {
        // Speed barrier inactive now, active at the predicted point: the tangent plane of
        // the sphere there, 0.5 k max(0, n.(y - x0) - r)^2.
        const Vec3& nd = s->switch_dir[a];
        add_rhs(t, t.k * (nd.dot(y - t.vec) - t.scalar) * nd);
        AddTermHessian(s, t, t.k * nd * nd.transpose());
      }
    }
  }
  for (int i = 0; i < 3 * n; ++i) s->rhs[i] = -(s->rhs[i] + s->grad[i]);
  if (!FactorBanded(s->min_pivot, &s->band)) return false;
  SolveWithColumns(s);
  for (double v : s->step)
    if (!std::isfinite(v)) return false;
  return true;
}

// Predicted activity of every switching term (contact planes, speed barriers) at x + step;
// returns true if any changed. Uses y at x from BuildBase.
bool UpdateSwitchActivity(System* s) {
  bool changed = false;
  int sw = 0;
  for (const std::vector<Term>* list : {&s->fixed_terms, &s->pair_terms}) {
    for (const Term& t : *list) {
      if (t.kind == Term::Kind::kSpring) continue;
      Vec3 y = s->sw_y[sw];
      for (int k = 0; k < t.count; ++k)
        if (s->dof[t.node[k]] >= 0)
          y += t.w[k] * Eigen::Map<const Vec3>(s->step.data() + 3 * t.node[k]);
      std::int8_t act = 0;
      if (t.kind == Term::Kind::kPlane) {
        act = t.scalar - t.vec.dot(y) > 0 ? 1 : 0;
      } else {
        const Vec3 d = y - t.vec;
        const double l = d.norm();
        act = l > t.scalar ? 1 : 0;
        if (act) s->switch_dir[sw] = d / l;
      }
      if (act != s->switch_active[sw]) changed = true;
      s->switch_active[sw++] = act;
    }
  }
  return changed;
}

// Activity of every switching term at the iterate (y from BuildBase).
void SetSwitchActivityAt(System* s) {
  s->switch_active.clear();
  s->switch_dir.clear();
  int sw = 0;
  for (const std::vector<Term>* list : {&s->fixed_terms, &s->pair_terms}) {
    for (const Term& t : *list) {
      if (t.kind == Term::Kind::kSpring) continue;
      const Vec3& y = s->sw_y[sw++];
      const bool act = t.kind == Term::Kind::kPlane ? t.scalar - t.vec.dot(y) > 0
                                                    : (y - t.vec).norm() > t.scalar;
      s->switch_active.push_back(act ? 1 : 0);
      s->switch_dir.push_back(Vec3::Zero());
    }
  }
}

int ProjectLengths(System* s, bool limit_only, int passes, Points* x);

// Stiffness of a stretch term at force lambda (compression is soft: a braid buckles).
double StretchStiffness(const Term& t, double lambda) { return lambda < 0 ? t.k_compress : t.k; }

void InitLambda(System* s, const Points& x) {
  s->lambda.resize(s->stretch_terms.size());
  for (std::size_t j = 0; j < s->stretch_terms.size(); ++j) {
    const Term& t = s->stretch_terms[j];
    const double c = (x.col(t.node[1]) - x.col(t.node[0])).norm() - t.scalar;
    s->lambda[j] = (c < 0 ? t.k_compress : t.k) * c;
  }
}

// Newton with a backtracking (Armijo) line search on the incremental potential, from *x.
// Every accepted iterate lowers the energy, so a step that is cut short by the iteration limit
// is still stable. Each iteration solves the model in which contact planes are exactly
// piecewise quadratic: the activity of the planes is predicted from the step and the system
// re-solved until it no longer changes (primal-dual active set), so Newton does not discover
// the contacts of a thread landing on tissue one per iteration. Returns the iteration count;
// *converged tells whether the update fell below the tolerance.
int NewtonSolve(System* s, const ThreadSolverParams& p, Points* x, bool* converged) {
  *converged = true;
  if (s->num_free == 0) return 0;
  const int n3 = 3 * s->num_nodes;
  InitLambda(s, *x);
  s->lambda_new.resize(s->lambda.size());
  double e0 = TotalEnergy(*s, *x);
  int it = 0;
  *converged = false;
  while (it < p.max_newton_iterations) {
    ++it;
    // Pass 0: activity at x (plain Newton step, a descent direction). Further passes: activity
    // predicted at x + step, kept only if it becomes consistent (then the step minimises the
    // exact piecewise-quadratic contact model, also a descent direction).
    bool negative = true;
    BuildBase(s, *x, true);
    SetSwitchActivityAt(s);
    auto solve = [&]() {
      if (negative && SolveModel(s)) return true;
      if (negative) BuildBase(s, *x, false);
      negative = false;
      return SolveModel(s);
    };
    if (!solve()) break;
    s->step0 = s->step;
    bool consistent = !UpdateSwitchActivity(s);
    for (int pass = 1; !consistent && pass < p.max_active_set_passes; ++pass) {
      if (!solve()) break;
      consistent = !UpdateSwitchActivity(s);
    }
    if (!consistent) s->step = s->step0;  // s->grad is the true gradient in every pass
    double slope = 0, step_max = 0;
    for (int i = 0; i < n3; ++i) {
      slope += s->grad[i] * s->step[i];
      step_max = std::max(step_max, std::abs(s->step[i]));
    }
    // Multipliers of the linearised stretch constraints: k (c + u . (dx1 - dx0)).
    for (std::size_t j = 0; j < s->stretch_terms.size(); ++j) {
      const Term& t = s->stretch_terms[j];
      const Vec3 e = x->col(t.node[1]) - x->col(t.node[0]);
      const double l = std::max(e.norm(), 1e-12);
      const Vec3 de = Eigen::Map<const Vec3>(s->step.data() + 3 * t.node[1]) -
                      Eigen::Map<const Vec3>(s->step.data() + 3 * t.node[0]);
      const double c = l - t.scalar + e.dot(de) / l;
      s->lambda_new[j] = (c < 0 ? t.k_compress : t.k) * c;
    }
    if (step_max < p.newton_tolerance_mm) {  // converged: take the tiny step without a search
      for (int i = 0; i < s->num_nodes; ++i)
        if (s->dof[i] >= 0) x->col(i) += Eigen::Map<const Vec3>(s->step.data() + 3 * i);
      *converged = true;
      break;
    }
    double alpha = 1.0;
    bool accepted = false;
    double e1 = e0;
    const int m = static_cast<int>(s->stretch_terms.size());
    s->tri_target.resize(m);
    s->tri_active.resize(m);
    for (int ls = 0; ls < 30; ++ls) {
      s->trial = *x;
      for (int i = 0; i < s->num_nodes; ++i)
        if (s->dof[i] >= 0)
          s->trial.col(i) += alpha * Eigen::Map<const Vec3>(s->step.data() + 3 * i);
      // Second-order correction: a straight step rotates stiff segments and so stretches
      // them to second order, which the energy would reject (Maratos effect; a falling chain
      // would crawl). Project the lengths onto their linearised values l + alpha u.(dx1 - dx0).
      for (int j = 0; j < m; ++j) {
        const double lam = s->lambda[j] + alpha * (s->lambda_new[j] - s->lambda[j]);
        s->tri_target[j] =
            s->stretch_terms[j].scalar + lam / StretchStiffness(s->stretch_terms[j], lam);
        s->tri_active[j] = 1;
      }
      ProjectLengths(s, false, 2, &s->trial);
      e1 = TotalEnergy(*s, s->trial);
      if (e1 <= e0 + 1e-4 * alpha * std::min(slope, 0.0)) {
        accepted = true;
        break;
      }
      alpha *= 0.5;
    }
    if (!accepted) {  // rounding floor: the energy cannot resolve the step any more
      *converged = step_max < 1e3 * p.newton_tolerance_mm;
      break;
    }
    for (std::size_t j = 0; j < s->stretch_terms.size(); ++j)
      s->lambda[j] += alpha * (s->lambda_new[j] - s->lambda[j]);
    std::swap(*x, s->trial);
    e0 = e1;
    if (alpha * step_max < p.newton_tolerance_mm) {
      *converged = true;
      break;
    }
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

// Contact term for segments a, b from their closest points cp; a0..b1 are the end points the
// closest points were computed on (used only for the normal of touching segments).
Term SegmentPairTerm(const System& s, int a, int b, double stiffness, const SegmentClosest& cp,
                     const Vec3& a0, const Vec3& a1, const Vec3& b0, const Vec3& b1) {
  const ThreadSegmentRef& sa = s.segments[a];
  const ThreadSegmentRef& sb = s.segments[b];
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
    const Vec3 da = a1 - a0, db = b1 - b0;
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
  const ThreadSegmentRef& sa = s.segments[a];
  const ThreadSegmentRef& sb = s.segments[b];
  if (sa.thread != sb.thread) return false;
  if (!models[sa.thread].self_collision) return true;
  const int i = std::min(sa.seg, sb.seg), j = std::max(sa.seg, sb.seg);
  if (j - i < 2) return true;
  const double gap = rest[sa.thread].arc_mm[j] - rest[sa.thread].arc_mm[i + 1];
  return gap < exclusion_factor * models[sa.thread].diameter_mm;
}

SweptSegments Swept(const System& s, int a, int b, const Points& x1) {
  const ThreadSegmentRef& sa = s.segments[a];
  const ThreadSegmentRef& sb = s.segments[b];
  return SweptSegments{s.x0.col(sa.n0), s.x0.col(sa.n1), s.x0.col(sb.n0), s.x0.col(sb.n1),
                       x1.col(sa.n0),   x1.col(sa.n1),   x1.col(sb.n0),   x1.col(sb.n1)};
}

// Segment pairs whose swept boxes (x0 -> x1, grown by pad_factor * radius) overlap and that are
// not excluded, into s->kept (sorted).
void CandidatePairs(System* s, const std::vector<ThreadModel>& models,
                    const std::vector<ThreadRest>& rest, const ThreadSolverParams& p,
                    const Points& x1, double pad_factor) {
  s->boxes.resize(s->segments.size());
  for (std::size_t i = 0; i < s->segments.size(); ++i) {
    const ThreadSegmentRef& sg = s->segments[i];
    s->boxes[i] = SweptSegmentBox(s->x0.col(sg.n0), s->x0.col(sg.n1), x1.col(sg.n0), x1.col(sg.n1),
                                  0.5 * s->seg_diameter[i] * pad_factor);
  }
  OverlappingPairs(s->boxes, &s->order, &s->pairs);
  s->kept.clear();
  for (const auto& pr : s->pairs)
    if (!PairExcluded(*s, models, rest, p.exclusion_factor, pr[0], pr[1])) s->kept.push_back(pr);
}

// Mass-weighted projection of segment lengths (fast projection, Goldenthal et al. 2007): each
// pass linearises the lengths of the active segments and solves the tridiagonal system
// (J W J^T) dlambda = l - target along the chains (Thomas algorithm; W = inverse masses, fixed
// nodes do not move), then moves x by -W J^T dlambda. Converges quadratically. s->tri_active
// and s->tri_target (mm) must be set for every stretch term; with limit_only, a segment joins
// the active set only once it is longer than its target (and stays in it).
int ProjectLengths(System* s, bool limit_only, int passes, Points* x) {
  const int m = static_cast<int>(s->stretch_terms.size());
  s->tri_a.resize(m);
  s->tri_b.resize(m);
  s->tri_c.resize(m);
  s->tri_r.resize(m);
  s->tri_u.resize(m);
  int joined = 0;
  s->tri_w.resize(s->num_nodes);
  for (int i = 0; i < s->num_nodes; ++i) s->tri_w[i] = s->dof[i] >= 0 ? 1.0 / s->mass[i] : 0.0;
  auto w = [&](int node) { return s->tri_w[node]; };
  // Chains: maximal runs of stretch terms that share nodes (a thread, or its pieces once cut).
  s->tri_chain.clear();
  int max_chain = 0;
  for (int j = 0; j < m; ++j) {
    if (j == 0 || s->stretch_terms[j].node[0] != s->stretch_terms[j - 1].node[1]) {
      if (j > 0) max_chain = std::max(max_chain, j - s->tri_chain.back());
      s->tri_chain.push_back(j);
    }
  }
  if (m > 0) max_chain = std::max(max_chain, m - s->tri_chain.back());
  s->tri_chain.push_back(m);
  for (int pass = 0; pass < passes; ++pass) {
    bool any = false;
    for (int j = 0; j < m; ++j) {
      const Term& t = s->stretch_terms[j];
      const Vec3 e = x->col(t.node[1]) - x->col(t.node[0]);
      const double l = e.norm();
      s->tri_u[j] = l > 0 ? Vec3(e / l) : Vec3::Zero();
      s->tri_r[j] = l - s->tri_target[j];
      if (w(t.node[0]) + w(t.node[1]) == 0 || l == 0) {
        s->tri_active[j] = 0;
        continue;
      }
      if (limit_only && !s->tri_active[j] && l > s->tri_target[j] * (1 + 1e-12)) {
        s->tri_active[j] = 1;
        ++joined;
      }
      if (s->tri_active[j] && std::abs(s->tri_r[j]) > 1e-12 * s->tri_target[j]) any = true;
    }
    if (!any) break;
    for (int j = 0; j < m; ++j) {
      const Term& t = s->stretch_terms[j];
      const bool act = s->tri_active[j];
      s->tri_b[j] = act ? w(t.node[0]) + w(t.node[1]) : 1.0;
      if (!act) s->tri_r[j] = 0;
      s->tri_c[j] = 0;
      if (act && j + 1 < m && s->tri_active[j + 1] && s->stretch_terms[j + 1].node[0] == t.node[1])
        s->tri_c[j] = -w(t.node[1]) * s->tri_u[j].dot(s->tri_u[j + 1]);
      s->tri_a[j] = j > 0 ? s->tri_c[j - 1] : 0.0;
    }
    // Thomas algorithm (positive definite, no pivoting) on every chain, the chains in lock
    // step: each row waits for a division on the previous one, so one chain alone leaves the
    // divider idle most of the time. (Rows of different chains never couple: c = 0 there.)
    const int nc = static_cast<int>(s->tri_chain.size()) - 1;
    for (int q = 1; q < max_chain; ++q) {
      for (int k = 0; k < nc; ++k) {
        const int j = s->tri_chain[k] + q;
        if (j >= s->tri_chain[k + 1]) continue;
        const double f = s->tri_a[j] / s->tri_b[j - 1];
        const double diag = s->tri_b[j];
        s->tri_b[j] -= f * s->tri_c[j - 1];
        // A redundant active set (a straight chain fixed at both ends has more length rows
        // than axial freedoms: J W J^T is singular) leaves a zero pivot, and 0/0 would poison
        // the thread; a floor keeps it positive (the null direction moves no node: J^T n = 0).
        if (!(s->tri_b[j] > 1e-12 * diag)) s->tri_b[j] = 1e-12 * diag;
        s->tri_r[j] -= f * s->tri_r[j - 1];
      }
    }
    for (int q = max_chain - 1; q >= 0; --q) {
      for (int k = 0; k < nc; ++k) {
        const int j = s->tri_chain[k] + q;
        if (j >= s->tri_chain[k + 1]) continue;
        if (j + 1 < s->tri_chain[k + 1]) s->tri_r[j] -= s->tri_c[j] * s->tri_r[j + 1];
        s->tri_r[j] /= s->tri_b[j];
      }
    }
    for (int j = 0; j < m; ++j) {
      if (s->tri_r[j] == 0) continue;
      const Term& t = s->stretch_terms[j];
      const Vec3 corr = s->tri_r[j] * s->tri_u[j];
      x->col(t.node[0]) += w(t.node[0]) * corr;
      x->col(t.node[1]) -= w(t.node[1]) * corr;
    }
  }
  return joined;
}

// Strain limit: a pull far beyond the suture's strength (or an unconverged iterate) may stretch
// a segment beyond lmax = (1 + max_strain) L0. Such segments are projected to lmax while every
// other segment keeps its current length (projecting only the violators would push the stretch
// into their neighbours, one segment per pass). Returns the number of segments limited.
int LimitStrain(System* s, double max_strain, int passes, Points* x) {
  const int m = static_cast<int>(s->stretch_terms.size());
  s->tri_active.assign(m, 1);
  s->tri_target.resize(m);
  int limited = 0;
  for (int j = 0; j < m; ++j) {
    const Term& t = s->stretch_terms[j];
    const double l = (x->col(t.node[1]) - x->col(t.node[0])).norm();
    const double lmax = (1 + max_strain) * t.scalar;
    if (l > lmax) ++limited;
    s->tri_target[j] = std::min(l, lmax);
  }
  if (limited == 0) return 0;
  ProjectLengths(s, false, passes, x);
  return limited;
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

  // ---- Global numbering. Every buffer lives in ws->scratch and keeps its capacity.
  System& s = ws->scratch;
  s.dt = dt_s;
  s.gravity = gravity_mm_s2;
  s.num_nodes = 0;
  s.num_free = 0;
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
  s.min_pivot.assign(s.num_nodes, 0.0);
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
      // The matrix is inertia + positive semi-definite terms, so its pivots are >= the
      // inertia; a pivot far below it means the negative geometric terms made it indefinite.
      s.min_pivot[g] = s.dof[g] >= 0 ? 1e-3 * s.inertia[g] : 0.5;
    }
  }

  // ---- Internal terms: stretch and bending.
  s.stretch_terms.clear();
  s.fixed_terms.clear();
  s.pair_terms.clear();
  s.pair_keys.clear();
  s.segments.clear();
  s.seg_diameter.clear();
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

  // ---- External contacts and springs (targets kThread only).
  s.contact_term.assign(contacts ? contacts->size() : 0, -1);
  s.spring_term.assign(springs ? springs->size() : 0, -1);
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
      s.contact_term[c] = static_cast<int>(s.fixed_terms.size());
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
      s.spring_term[c] = static_cast<int>(s.fixed_terms.size());
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
  auto add_pair = [&](int a, int b, const SegmentClosest& cp, const Vec3& a0, const Vec3& a1,
                      const Vec3& b0, const Vec3& b1) {
    const std::array<int, 2> key{a, b};
    auto it = std::lower_bound(s.pair_keys.begin(), s.pair_keys.end(), key);
    if (it != s.pair_keys.end() && *it == key) return false;
    const std::size_t pos = static_cast<std::size_t>(it - s.pair_keys.begin());
    s.pair_keys.insert(it, key);
    s.pair_terms.insert(s.pair_terms.begin() + static_cast<std::ptrdiff_t>(pos),
                        SegmentPairTerm(s, a, b, kc, cp, a0, a1, b0, b1));
    return true;
  };
  if (!s.segments.empty()) {
    const double pad = 1.0 + p.contact_margin_factor;
    CandidatePairs(&s, threads, ws->rest, p, s.x0, pad);
    for (const auto& pr : s.kept) {
      const ThreadSegmentRef& sa = s.segments[pr[0]];
      const ThreadSegmentRef& sb = s.segments[pr[1]];
      const Vec3 a0 = s.x0.col(sa.n0), a1 = s.x0.col(sa.n1);
      const Vec3 b0 = s.x0.col(sb.n0), b1 = s.x0.col(sb.n1);
      const SegmentClosest cp = ClosestPointsSegments(a0, a1, b0, b1);
      const double dist = 0.5 * (s.seg_diameter[pr[0]] + s.seg_diameter[pr[1]]);
      if (cp.distance < pad * dist) add_pair(pr[0], pr[1], cp, a0, a1, b0, b1);
    }
  }

  // ---- Solve, then continuous detection and re-solve. Newton starts from x0, which is on the
  // length constraints; the explicit guess x0 + dt v0 of a moving slack chain is not (its
  // stretch energy can be 1e5 times the step's), and on the benchmark scene it keeps Newton
  // at its iteration cap. The step energy is not convex for a compressed chain, so the start
  // can decide which minimum a step finds (an arch draped over another thread is one such case).
  s.x = s.x0;
  Points& x = s.x;
  for (int round = 0;; ++round) {
    bool converged = false;
    const int iters = NewtonSolve(&s, p, &x, &converged);
    ws->last.newton_iterations += iters;
    ws->last.max_newton_per_solve = std::max(ws->last.max_newton_per_solve, iters);
    if (!converged) ++ws->last.unconverged_solves;
    ws->last.strain_limited_segments += LimitStrain(&s, p.max_strain, p.strain_limit_passes, &x);
    ++ws->last.solves;
    if (s.segments.empty() || round >= p.max_ccd_rounds) break;
    bool added = false;
    CandidatePairs(&s, threads, ws->rest, p, x, 1.0);
    for (const auto& pr : s.kept) {
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
      const Vec3 a0 = sw.a0_start + t_ref * (sw.a0_end - sw.a0_start);
      const Vec3 a1 = sw.a1_start + t_ref * (sw.a1_end - sw.a1_start);
      const Vec3 b0 = sw.b0_start + t_ref * (sw.b0_end - sw.b0_start);
      const Vec3 b1 = sw.b1_start + t_ref * (sw.b1_end - sw.b1_start);
      const SegmentClosest cp = ClosestPointsSegments(a0, a1, b0, b1);
      added |= add_pair(pr[0], pr[1], cp, a0, a1, b0, b1);
    }
    if (!added) break;
  }
  ws->last.contact_pairs = static_cast<int>(s.pair_terms.size());

  // ---- Fail-safe: revert every thread involved in a crossing to its start-of-step position
  // (whole threads, so no segment is torn). x0 is crossing-free, so this terminates.
  if (!s.segments.empty()) {
    s.frozen.assign(nt, 0);
    CandidatePairs(&s, threads, ws->rest, p, x, 1.0);
    for (int pass = 0; pass <= nt; ++pass) {
      bool any = false;
      for (const auto& pr : s.kept) {
        const SweptResult res =
            SweptSegmentTest(Swept(s, pr[0], pr[1], x), p.crossing_tolerance_mm, 1);
        if (!res.crosses) continue;
        for (int seg : pr) {
          const int t = s.segments[seg].thread;
          if (s.frozen[t]) continue;
          s.frozen[t] = 1;
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
      if (s.contact_term[c] < 0) continue;
      const Term& t = s.fixed_terms[s.contact_term[c]];
      TermEval(t, TermY(t, x), &g, nullptr);
      (*contacts)[c].force_n = g.norm() * units::kInternalForceToNewton;
    }
  }
  if (springs) {
    for (std::size_t c = 0; c < springs->size(); ++c) {
      if ((*springs)[c].target != PointContact::Target::kThread) continue;
      (*springs)[c].force_n.setZero();
      if (s.spring_term[c] < 0) continue;
      const Term& t = s.fixed_terms[s.spring_term[c]];
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
