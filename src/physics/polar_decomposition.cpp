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
    const Mat3 inv_t = x.inverse().transpose();
    // Frobenius scaling (Higham) for the first steps; plain Newton near convergence.
    double gamma = 1.0;
    if (it < 6) gamma = std::sqrt(std::sqrt(inv_t.squaredNorm() / x.squaredNorm()));
    const Mat3 next = 0.5 * (gamma * x + inv_t / gamma);
    const double change = (next - x).squaredNorm();
    x = next;
    if (change <= 1e-30 * 3.0) break;
  }
  return x;
}

}  // namespace arthrosim::physics
