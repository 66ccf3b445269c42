#include "arthrosim/physics/thread_band_solver.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>

namespace arthrosim::physics {

void ResetBanded(int n, BandedBlockMatrix* a) {
  a->n = n;
  a->diag.resize(n);
  a->sub1.resize(n);
  a->sub2.resize(n);
  for (int i = 0; i < n; ++i) {
    a->diag[i].setZero();
    a->sub1[i].setZero();
    a->sub2[i].setZero();
  }
}

void AddBandedBlock(int row, int col, const Mat3& h, BandedBlockMatrix* a) {
  if (row == col) {
    a->diag[row] += h;
  } else if (row == col + 1) {
    a->sub1[col] += h;
  } else if (row == col + 2) {
    a->sub2[col] += h;
  } else if (col == row + 1) {
    a->sub1[row] += h.transpose();
  } else {
    a->sub2[row] += h.transpose();  // col == row + 2
  }
}

bool FactorBanded(const std::vector<double>& min_pivot, BandedBlockMatrix* a) {
  // Block Cholesky A = L L^T: the same arithmetic as scalar Cholesky, so it stays accurate on
  // a chain whose axial stiffness exceeds its inertia by 1e10 (an explicit D^-1 would not).
  for (int i = 0; i < a->n; ++i) {
    Eigen::LLT<Mat3> llt(a->diag[i]);  // diag[i] holds the Schur complement by now
    if (llt.info() != Eigen::Success) return false;
    const Mat3 lii = llt.matrixL();
    const double piv = std::min({lii(0, 0), lii(1, 1), lii(2, 2)});
    if (!(piv * piv > min_pivot[i])) return false;
    a->diag[i] = lii;
    const Mat3 b1 = lii.triangularView<Eigen::Lower>().solve(a->sub1[i].transpose()).transpose();
    const Mat3 b2 = lii.triangularView<Eigen::Lower>().solve(a->sub2[i].transpose()).transpose();
    a->sub1[i] = b1;
    a->sub2[i] = b2;
    if (i + 1 < a->n) {
      a->diag[i + 1] -= b1 * b1.transpose();
      if (i + 2 < a->n) {
        a->diag[i + 2] -= b2 * b2.transpose();
        a->sub1[i + 1] -= b2 * b1.transpose();
      }
    }
  }
  return true;
}

void SolveBanded(const BandedBlockMatrix& a, const double* b, double* x) {
  const int n = a.n;
  using CMap = Eigen::Map<const Vec3>;
  using Map = Eigen::Map<Vec3>;
  for (int i = 0; i < n; ++i) {  // L y = b
    Vec3 y = CMap(b + 3 * i);
    if (i >= 1) y -= a.sub1[i - 1] * Map(x + 3 * (i - 1));
    if (i >= 2) y -= a.sub2[i - 2] * Map(x + 3 * (i - 2));
    Map(x + 3 * i) = a.diag[i].triangularView<Eigen::Lower>().solve(y);
  }
  for (int i = n - 1; i >= 0; --i) {  // L^T x = y
    Vec3 z = Map(x + 3 * i);
    if (i + 1 < n) z -= a.sub1[i].transpose() * Map(x + 3 * (i + 1));
    if (i + 2 < n) z -= a.sub2[i].transpose() * Map(x + 3 * (i + 2));
    Map(x + 3 * i) = a.diag[i].transpose().triangularView<Eigen::Upper>().solve(z);
  }
}

}  // namespace arthrosim::physics
