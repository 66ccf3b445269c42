#include "arthrosim/physics/polar_decomposition.h"

#include <Eigen/SVD>
#include <cmath>

namespace arthrosim::physics {
namespace {

// Rotation from an SVD, with the reflection (if any) pushed onto the smallest singular value.
Mat3 SvdRotation(const Mat3& f) {
  const Eigen::JacobiSVD<Mat3> svd(f, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Mat3 u = svd.matrixU();
  const Mat3& v = svd.matrixV();
  if ((u * v.transpose()).determinant() < 0) u.col(2) = -u.col(2);  // singular values sorted
  return u * v.transpose();
}

}  // namespace

Mat3 PolarRotation(const Mat3& f) {
  if (!f.allFinite()) return Mat3::Identity();
  const double norm2 = f.squaredNorm();
  if (norm2 == 0) return Mat3::Identity();
  // det relative to the cube of the mean singular value: small or negative means flat/inverted,
  // where Newton converges slowly or to a reflection.
  const double scale = std::sqrt(norm2 / 3.0);
  if (f.determinant() <= 1e-3 * scale * scale * scale) return SvdRotation(f);
  Mat3 x = f;
  for (int it = 0; it < 30; ++it) {
    // X^-T = cofactor(X) / det(X), written out (the 3x3 inverse without Eigen's generic path).
    Mat3 cof;
    cof.col(0) = x.col(1).cross(x.col(2));
    cof.col(1) = x.col(2).cross(x.col(0));
    cof.col(2) = x.col(0).cross(x.col(1));
    const double inv_det = 1.0 / x.col(0).dot(cof.col(0));
    const double inv_norm2 = cof.squaredNorm() * (inv_det * inv_det);  // |X^-1|_F^2
    // Frobenius scaling (Higham) for the first steps; plain Newton near convergence.
    double gamma = 1.0;
    if (it < 6) gamma = std::sqrt(std::sqrt(inv_norm2 / x.squaredNorm()));
    const Mat3 next = (0.5 * gamma) * x + (0.5 * inv_det / gamma) * cof;
    const double change = (next - x).squaredNorm();
    x = next;
    // Newton converges quadratically: a step of size d leaves an error of about |X^-1| d^2 / 2;
    // stop once that is below 1e-16 (round-off level).
    if (0.25 * inv_norm2 * change * change <= 1e-32) break;
  }
  return x;
}

}  // namespace arthrosim::physics
