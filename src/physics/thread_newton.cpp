// The thread solver's Newton solve: banded Newton matrix (inertia, stretch, bending, point
// terms) plus off-band rank-1 columns for segment-segment contacts (Woodbury), an active-set
// model of the contact planes, a backtracking line search, and the strain-limit projection.
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

#include "thread_internal.h"

namespace arthrosim::physics::thread_internal {
namespace {

// Stretch energy 0.5 k(c) c^2 of segment j, c = l - L (stiffness k_compress when c < 0).
double StretchEnergy(const Term& t, const Points& x) {
  const double c = (x.col(t.node[1]) - x.col(t.node[0])).norm() - t.scalar;
  return 0.5 * (c < 0 ? t.k_compress : t.k) * c * c;
}

// Energy of every group at x, into *e (the incremental potential is their sum).
void GroupEnergies(const System& s, const Points& x, std::vector<double>* e) {
  e->assign(s.num_groups, 0.0);
  for (int i = 0; i < s.num_nodes; ++i) {
    if (s.dof[i] < 0) continue;
    const Vec3 dx = x.col(i) - s.x0.col(i);
    (*e)[s.node_group[i]] += 0.5 * s.inertia[i] * dx.squaredNorm() -
                             s.mass[i] * (dx.dot(s.v0.col(i)) / s.dt + dx.dot(s.gravity));
  }
  for (std::size_t j = 0; j < s.stretch_terms.size(); ++j)
    (*e)[s.stretch_group[j]] += StretchEnergy(s.stretch_terms[j], x);
  for (const std::vector<Term>* list : {&s.fixed_terms, &s.pair_terms})
    for (const Term& t : *list)
      (*e)[s.node_group[t.node[0]]] += TermEval(t, TermY(t, x), nullptr, nullptr);
}

// Groups: connected components of the nodes under the terms that couple them (stretch,
// bending, multi-node point terms, segment-segment contacts), numbered in node order. Fills
// s->node_group, s->stretch_group, s->switch_group and sizes the per-group buffers.
void FindGroups(System* s) {
  const int n = s->num_nodes;
  std::vector<int>& root = s->node_group;  // union-find parent; a root is its smallest node
  root.resize(n);
  for (int i = 0; i < n; ++i) root[i] = i;
  auto find = [&](int i) {
    while (root[i] != i) {
      root[i] = root[root[i]];
      i = root[i];
    }
    return i;
  };
  auto unite = [&](int a, int b) {
    a = find(a);
    b = find(b);
    if (a < b)
      root[b] = a;
    else if (b < a)
      root[a] = b;
  };
  for (const Term& t : s->stretch_terms) unite(t.node[0], t.node[1]);
  for (const std::vector<Term>* list : {&s->fixed_terms, &s->pair_terms})
    for (const Term& t : *list)
      for (int k = 1; k < t.count; ++k) unite(t.node[0], t.node[k]);
  // Point every node at its root, then number the roots in node order: a root is the
  // smallest node of its group, so it is labelled (-1 - id) before its other nodes copy it.
  for (int i = 0; i < n; ++i) root[i] = find(i);
  int groups = 0;
  for (int i = 0; i < n; ++i) root[i] = root[i] == i ? -1 - groups++ : root[root[i]];
  for (int i = 0; i < n; ++i) root[i] = -1 - root[i];
  s->num_groups = groups;
  s->stretch_group.resize(s->stretch_terms.size());
  for (std::size_t j = 0; j < s->stretch_terms.size(); ++j)
    s->stretch_group[j] = root[s->stretch_terms[j].node[0]];
  s->switch_group.clear();
  for (const std::vector<Term>* list : {&s->fixed_terms, &s->pair_terms})
    for (const Term& t : *list)
      if (t.kind != Term::Kind::kSpring) s->switch_group.push_back(root[t.node[0]]);
  for (std::vector<std::uint8_t>* v : {&s->group_changed, &s->group_consistent, &s->group_done,
                                       &s->group_converged, &s->group_pending})
    v->assign(groups, 0);
  for (std::vector<double>* v :
       {&s->group_alpha, &s->group_e0, &s->group_e1, &s->group_slope, &s->group_step_max})
    v->assign(groups, 0.0);
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
    int rows[4];
    int count = 0;
    for (int k = 0; k < 4; ++k) {
      const int node = s->cols_node[4 * c + k];
      if (node < 0 || s->dof[node] < 0) continue;
      Eigen::Map<Vec3>(v + 3 * node) += s->cols_node_w[4 * c + k] * s->cols_dir[c];
      rows[count++] = node;
    }
    SolveBandedSparse(s->band, rows, count, v);
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
// returns true if any changed, and flags the groups of the changed ones in s->group_changed
// (the caller clears it). Uses y at x from BuildBase.
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
      if (act != s->switch_active[sw]) {
        changed = true;
        s->group_changed[s->switch_group[sw]] = 1;
      }
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

}  // namespace

// Newton with a backtracking (Armijo) line search on the incremental potential, from *x.
// Every accepted iterate lowers the energy, so a step that is cut short by the iteration limit
// is still stable. Each iteration solves the model in which contact planes are exactly
// piecewise quadratic: the activity of the planes is predicted from the step and the system
// re-solved until it no longer changes (primal-dual active set), so Newton does not discover
// the contacts of a thread landing on tissue one per iteration. The energy is a sum over
// independent groups (FindGroups; the Newton matrix is block diagonal over them), so each group
// keeps its own consistent active set, line-search factor and convergence: a thread whose
// contacts stay inconsistent does not hold back another. Returns the iteration count;
// *converged tells whether every group's update fell below the tolerance.
int NewtonSolve(System* s, const ThreadSolverParams& p, Points* x, bool* converged) {
  *converged = true;
  if (s->num_free == 0) return 0;
  const int n = s->num_nodes;
  InitLambda(s, *x);
  s->lambda_new.resize(s->lambda.size());
  FindGroups(s);
  const int ng = s->num_groups;
  // A group without a free node has nothing to solve.
  for (int i = 0; i < n; ++i)
    if (s->dof[i] >= 0) s->group_pending[s->node_group[i]] = 1;
  for (int g = 0; g < ng; ++g) s->group_done[g] = s->group_converged[g] = !s->group_pending[g];
  GroupEnergies(*s, *x, &s->group_e0);
  auto all_done = [&]() {
    for (int g = 0; g < ng; ++g)
      if (!s->group_done[g]) return false;
    return true;
  };
  // Copies the nodes of the groups flagged in `which` from `from` (3 n values) into `to`.
  auto copy_groups = [&](const std::vector<std::uint8_t>& which, const std::vector<double>& from,
                         std::vector<double>* to) {
    for (int i = 0; i < n; ++i)
      if (which[s->node_group[i]])
        for (int c = 0; c < 3; ++c) (*to)[3 * i + c] = from[3 * i + c];
  };
  int it = 0;
  while (it < p.max_newton_iterations && !all_done()) {
    ++it;
    // Pass 0: activity at x (plain Newton step, a descent direction). Further passes: activity
    // predicted at x + step; a group keeps the step of the pass whose prediction did not change
    // its activity (it minimises the exact piecewise-quadratic contact model, also a descent
    // direction), else its pass-0 step.
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
    s->step_kept = s->step;
    s->group_changed.assign(ng, 0);
    UpdateSwitchActivity(s);
    bool all_consistent = true;
    for (int g = 0; g < ng; ++g) {
      s->group_consistent[g] = s->group_done[g] || !s->group_changed[g];
      all_consistent = all_consistent && s->group_consistent[g];
    }
    for (int pass = 1; !all_consistent && pass < p.max_active_set_passes; ++pass) {
      if (!solve()) break;
      s->group_changed.assign(ng, 0);
      UpdateSwitchActivity(s);
      all_consistent = true;
      for (int g = 0; g < ng; ++g) {
        // Newly consistent: its step is final (its activity, so its step, no longer changes).
        s->group_pending[g] = !s->group_consistent[g] && !s->group_changed[g];
        if (s->group_pending[g]) s->group_consistent[g] = 1;
        all_consistent = all_consistent && s->group_consistent[g];
      }
      copy_groups(s->group_pending, s->step, &s->step_kept);
    }
    std::swap(s->step, s->step_kept);  // s->grad is the true gradient in every pass
    for (int g = 0; g < ng; ++g) s->group_slope[g] = s->group_step_max[g] = 0;
    for (int i = 0; i < n; ++i) {
      if (s->dof[i] < 0) continue;
      const int g = s->node_group[i];
      for (int c = 0; c < 3; ++c) {
        s->group_slope[g] += s->grad[3 * i + c] * s->step[3 * i + c];
        s->group_step_max[g] = std::max(s->group_step_max[g], std::abs(s->step[3 * i + c]));
      }
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
    // A group whose step is below the tolerance has converged: it takes the tiny step without
    // a search. The others search their factor each.
    for (int g = 0; g < ng; ++g) {
      s->group_pending[g] = 0;
      s->group_changed[g] = 0;
      s->group_alpha[g] = 1.0;
      if (s->group_done[g]) continue;
      if (s->group_step_max[g] < p.newton_tolerance_mm) {
        s->group_done[g] = s->group_converged[g] = 1;
        s->group_changed[g] = 1;  // flags the groups that take their full step now
      } else {
        s->group_pending[g] = 1;
      }
    }
    for (int i = 0; i < n; ++i)
      if (s->dof[i] >= 0 && s->group_changed[s->node_group[i]])
        x->col(i) += Eigen::Map<const Vec3>(s->step.data() + 3 * i);
    s->x_next = *x;
    const int m = static_cast<int>(s->stretch_terms.size());
    s->tri_target.resize(m);
    s->tri_active.resize(m);
    bool searching = false;
    for (int g = 0; g < ng; ++g) searching = searching || s->group_pending[g];
    for (int ls = 0; searching && ls < 30; ++ls) {
      s->trial = *x;
      for (int i = 0; i < n; ++i) {
        const int g = s->node_group[i];
        if (s->dof[i] >= 0 && s->group_pending[g])
          s->trial.col(i) += s->group_alpha[g] * Eigen::Map<const Vec3>(s->step.data() + 3 * i);
      }
      // Second-order correction: a straight step rotates stiff segments and so stretches
      // them to second order, which the energy would reject (Maratos effect; a falling chain
      // would crawl). Project the lengths onto their linearised values l + alpha u.(dx1 - dx0).
      for (int j = 0; j < m; ++j) {
        const int g = s->stretch_group[j];
        const double lam = s->lambda[j] + s->group_alpha[g] * (s->lambda_new[j] - s->lambda[j]);
        s->tri_target[j] =
            s->stretch_terms[j].scalar + lam / StretchStiffness(s->stretch_terms[j], lam);
        s->tri_active[j] = s->group_pending[g];
      }
      ProjectLengths(s, false, 2, &s->trial);
      GroupEnergies(*s, s->trial, &s->group_e1);
      searching = false;
      for (int g = 0; g < ng; ++g) {
        s->group_changed[g] = 0;  // flags the groups accepted in this round
        if (!s->group_pending[g]) continue;
        const double alpha = s->group_alpha[g];
        if (s->group_e1[g] <= s->group_e0[g] + 1e-4 * alpha * std::min(s->group_slope[g], 0.0)) {
          s->group_changed[g] = 1;
          s->group_pending[g] = 0;
          s->group_e0[g] = s->group_e1[g];
          if (alpha * s->group_step_max[g] < p.newton_tolerance_mm)
            s->group_done[g] = s->group_converged[g] = 1;
        } else {
          s->group_alpha[g] = 0.5 * alpha;
          searching = true;
        }
      }
      for (int i = 0; i < n; ++i)
        if (s->group_changed[s->node_group[i]]) s->x_next.col(i) = s->trial.col(i);
      for (int j = 0; j < m; ++j) {
        const int g = s->stretch_group[j];
        if (s->group_changed[g])
          s->lambda[j] += s->group_alpha[g] * (s->lambda_new[j] - s->lambda[j]);
      }
    }
    for (int g = 0; g < ng; ++g) {
      if (!s->group_pending[g]) continue;
      // Rounding floor: the energy cannot resolve the group's step any more.
      s->group_done[g] = 1;
      s->group_converged[g] = s->group_step_max[g] < 1e3 * p.newton_tolerance_mm;
    }
    std::swap(*x, s->x_next);
  }
  *converged = true;
  for (int g = 0; g < ng; ++g) *converged = *converged && s->group_converged[g];
  return it;
}

namespace {

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

}  // namespace

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

}  // namespace arthrosim::physics::thread_internal
