#pragma once
// Preconditioned conjugate gradients for the symmetric positive-definite step systems.
// All dot products are plain sequential sums in index order, so the result does not depend on
// the thread count even when the operator parallelises its product.
#include <Eigen/Core>

namespace arthrosim::physics {

/// A symmetric positive-definite operator with a preconditioner z = P^-1 r.
class SpdOperator {
 public:
  virtual ~SpdOperator() = default;
  /// y = A x.
  virtual void Apply(const Eigen::VectorXd& x, Eigen::VectorXd* y) const = 0;
  /// z = P^-1 r (P approximates A; the identity is allowed).
  virtual void Precondition(const Eigen::VectorXd& r, Eigen::VectorXd* z) const = 0;
};

struct CgResult {
  int iterations = 0;
  double relative_residual = 0;  ///< |b - A x| / max(|b|, reference) (recursive residual)
  bool converged = false;
};

/// Work vectors of SolvePcg, kept by the caller so a steady-state solve allocates nothing.
struct CgScratch {
  Eigen::VectorXd r, z, p, q;
};

/// Solves A x = b starting from *x (warm start). Stops when |r| <= tolerance max(|b|,
/// reference_norm) or after max_iterations products. reference_norm is the right-hand side
/// scale that sets the required accuracy (0: relative to |b| alone); it keeps a nearly
/// balanced system (|b| -> 0) from chasing round-off. b = 0 gives x = 0 with no iteration.
/// A warm start that already meets the tolerance costs one product and no preconditioning.
/// scratch (optional) holds the work vectors between calls.
CgResult SolvePcg(const SpdOperator& a, const Eigen::VectorXd& b, Eigen::VectorXd* x,
                  int max_iterations, double tolerance, double reference_norm = 0,
                  CgScratch* scratch = nullptr);

}  // namespace arthrosim::physics
