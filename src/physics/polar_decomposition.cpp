#include "arthrosim/physics/polar_decomposition.h"

#include <Eigen/SVD>
#include <algorithm>
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

void PolarRotations(const Mat3* f, Mat3* r, int count) {
  constexpr int kLanes = 4;
  // Structure of arrays, one lane per matrix: the Newton steps of kLanes matrices run side by
  // side (vectorised). A lane is frozen once its own stop test passes, so its result does not
  // depend on its neighbours (nor on how the caller batches).
  alignas(32) double x[9][kLanes];
  alignas(32) double nx[9][kLanes];
  for (int base = 0; base < count; base += kLanes) {
    const int n = std::min(kLanes, count - base);
    int lane_of[kLanes];
    int m = 0;
    for (int l = 0; l < n; ++l) {
      const Mat3& fl = f[base + l];
      const double norm2 = fl.squaredNorm();
      const double scale = std::sqrt(norm2 / 3.0);
      if (!fl.allFinite() || norm2 == 0 || fl.determinant() <= 1e-3 * scale * scale * scale) {
        r[base + l] = PolarRotation(fl);  // identity or SVD path
        continue;
      }
      lane_of[m] = base + l;
      for (int k = 0; k < 9; ++k) x[k][m] = fl.data()[k];
      ++m;
    }
    if (m == 0) continue;
    for (int l = m; l < kLanes; ++l) {  // idle lanes: identity (converges at once)
      for (int k = 0; k < 9; ++k) x[k][l] = (k % 4 == 0) ? 1.0 : 0.0;
    }
    bool done[kLanes] = {false, false, false, false};
    for (int it = 0; it < 30; ++it) {
      double stop[kLanes];
      for (int l = 0; l < kLanes; ++l) {
        // Column-major: x[c * 3 + row]. Cofactor columns: c0 = x1 x x2, c1 = x2 x x0, c2 = x0 x x1.
        const double a0 = x[0][l], a1 = x[1][l], a2 = x[2][l];
        const double b0 = x[3][l], b1 = x[4][l], b2 = x[5][l];
        const double c0 = x[6][l], c1 = x[7][l], c2 = x[8][l];
        double cof[9];
        cof[0] = b1 * c2 - b2 * c1;
        cof[1] = b2 * c0 - b0 * c2;
        cof[2] = b0 * c1 - b1 * c0;
        cof[3] = c1 * a2 - c2 * a1;
        cof[4] = c2 * a0 - c0 * a2;
        cof[5] = c0 * a1 - c1 * a0;
        cof[6] = a1 * b2 - a2 * b1;
        cof[7] = a2 * b0 - a0 * b2;
        cof[8] = a0 * b1 - a1 * b0;
        const double inv_det = 1.0 / (a0 * cof[0] + a1 * cof[1] + a2 * cof[2]);
        double cn = 0, xn = 0;
        for (int k = 0; k < 9; ++k) cn += cof[k] * cof[k];
        for (int k = 0; k < 9; ++k) xn += x[k][l] * x[k][l];
        const double inv_norm2 = cn * (inv_det * inv_det);
        const double gamma = it < 6 ? std::sqrt(std::sqrt(inv_norm2 / xn)) : 1.0;
        const double ga = 0.5 * gamma;
        const double gb = 0.5 * inv_det / gamma;
        double change = 0;
        for (int k = 0; k < 9; ++k) {
          nx[k][l] = ga * x[k][l] + gb * cof[k];
          const double d = nx[k][l] - x[k][l];
          change += d * d;
        }
        stop[l] = 0.25 * inv_norm2 * change * change <= 1e-32 ? 1.0 : 0.0;
      }
      bool all = true;
      for (int l = 0; l < kLanes; ++l) {
        if (!done[l]) {
          for (int k = 0; k < 9; ++k) x[k][l] = nx[k][l];
          if (stop[l] != 0) done[l] = true;
        }
        all = all && (done[l] || l >= m);
      }
      if (all) break;
    }
    for (int l = 0; l < m; ++l) {
      Mat3& out = r[lane_of[l]];
      for (int k = 0; k < 9; ++k) out.data()[k] = x[k][l];
    }
  }
}

}  // namespace arthrosim::physics
