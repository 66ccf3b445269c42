#include "arthrosim/physics/cg_solver.h"

#include <algorithm>
#include <cmath>

namespace arthrosim::physics {
namespace {

// Sequential dot product: Eigen's may vectorise with a layout-dependent order; this one is fixed.
double Dot(const Eigen::VectorXd& a, const Eigen::VectorXd& b) {
  double s = 0;
  const Eigen::Index n = a.size();
  const double* pa = a.data();
  const double* pb = b.data();
  for (Eigen::Index i = 0; i < n; ++i) s += pa[i] * pb[i];
  return s;
}

}  // namespace

CgResult SolvePcg(const SpdOperator& a, const Eigen::VectorXd& b, Eigen::VectorXd* x,
                  int max_iterations, double tolerance, double reference_norm, CgScratch* scratch) {
  CgResult result;
  const double b_norm = std::sqrt(Dot(b, b));
  if (b_norm == 0 || !std::isfinite(b_norm)) {
    x->setZero();
    return result;
  }
  const double scale = std::max(b_norm, reference_norm);
  const Eigen::Index n = b.size();
  CgScratch local;
  CgScratch& w = scratch ? *scratch : local;
  w.r.resize(n);
  w.z.resize(n);
  w.p.resize(n);
  w.q.resize(n);
  Eigen::VectorXd &r = w.r, &z = w.z, &p = w.p, &q = w.q;
  a.Apply(*x, &q);
  r = b - q;
  double r_norm = std::sqrt(Dot(r, r));
  // A warm start worse than zero is dropped.
  if (!(r_norm < b_norm)) {
    x->setZero();
    r = b;
    r_norm = b_norm;
  }
  int it = 0;
  if (r_norm <= tolerance * scale) {  // the warm start is already accurate enough
    result.relative_residual = r_norm / scale;
    result.converged = true;
    return result;
  }
  a.Precondition(r, &z);
  p = z;
  double rz = Dot(r, z);
  while (r_norm > tolerance * scale && it < max_iterations) {
    a.Apply(p, &q);
    const double pq = Dot(p, q);
    if (!(pq > 0)) break;  // breakdown (not SPD in floating point): keep the current x
    const double alpha = rz / pq;
    *x += alpha * p;
    r -= alpha * q;
    ++it;
    r_norm = std::sqrt(Dot(r, r));
    if (r_norm <= tolerance * scale) break;
    a.Precondition(r, &z);
    const double rz_next = Dot(r, z);
    const double beta = rz_next / rz;
    rz = rz_next;
    p = z + beta * p;
  }
  result.iterations = it;
  result.relative_residual = r_norm / scale;
  result.converged = r_norm <= tolerance * scale;
  return result;
}

}  // namespace arthrosim::physics
