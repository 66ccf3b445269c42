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
  constexpr int kLanes = 8;
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
    bool done[kLanes] = {};
    for (int it = 0; it < 30; ++it) {
      // Every operation is a loop over the lanes (innermost), so it compiles to packed SIMD.
      // Column-major: x[c * 3 + row]. Cofactor columns: c0 = x1 x x2, c1 = x2 x x0, c2 = x0 x x1.
      alignas(32) double cof[9][kLanes], inv_det[kLanes], inv_norm2[kLanes], ga[kLanes], gb[kLanes],
          change[kLanes];
      for (int l = 0; l < kLanes; ++l) {
        cof[0][l] = x[4][l] * x[8][l] - x[5][l] * x[7][l];
        cof[1][l] = x[5][l] * x[6][l] - x[3][l] * x[8][l];
        cof[2][l] = x[3][l] * x[7][l] - x[4][l] * x[6][l];
        cof[3][l] = x[7][l] * x[2][l] - x[8][l] * x[1][l];
        cof[4][l] = x[8][l] * x[0][l] - x[6][l] * x[2][l];
        cof[5][l] = x[6][l] * x[1][l] - x[7][l] * x[0][l];
        cof[6][l] = x[1][l] * x[5][l] - x[2][l] * x[4][l];
        cof[7][l] = x[2][l] * x[3][l] - x[0][l] * x[5][l];
        cof[8][l] = x[0][l] * x[4][l] - x[1][l] * x[3][l];
      }
      alignas(32) double cn[kLanes] = {}, xn[kLanes] = {};
      for (int k = 0; k < 9; ++k) {
        for (int l = 0; l < kLanes; ++l) {
          cn[l] += cof[k][l] * cof[k][l];
          xn[l] += x[k][l] * x[k][l];
        }
      }
      for (int l = 0; l < kLanes; ++l) {
        inv_det[l] = 1.0 / (x[0][l] * cof[0][l] + x[1][l] * cof[1][l] + x[2][l] * cof[2][l]);
        inv_norm2[l] = cn[l] * (inv_det[l] * inv_det[l]);
        change[l] = 0;
      }
      // Frobenius scaling (Higham) for the first steps; plain Newton near convergence.
      if (it < 6) {
        for (int l = 0; l < kLanes; ++l) {
          const double gamma = std::sqrt(std::sqrt(inv_norm2[l] / xn[l]));
          ga[l] = 0.5 * gamma;
          gb[l] = 0.5 * inv_det[l] / gamma;
        }
      } else {
        for (int l = 0; l < kLanes; ++l) {
          ga[l] = 0.5;
          gb[l] = 0.5 * inv_det[l];
        }
      }
      for (int k = 0; k < 9; ++k) {
        for (int l = 0; l < kLanes; ++l) {
          nx[k][l] = ga[l] * x[k][l] + gb[l] * cof[k][l];
          const double d = nx[k][l] - x[k][l];
          change[l] += d * d;
        }
      }
      bool all = true;
      for (int l = 0; l < kLanes; ++l) {
        if (!done[l]) {
          for (int k = 0; k < 9; ++k) x[k][l] = nx[k][l];
          // Newton converges quadratically: a step of size d leaves an error of about
          // |X^-1| d^2 / 2; stop once that is below 1e-16 (round-off level).
          if (0.25 * inv_norm2[l] * change[l] * change[l] <= 1e-32) done[l] = true;
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
