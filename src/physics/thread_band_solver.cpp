#include "arthrosim/physics/thread_band_solver.h"

#include <algorithm>
#include <array>
#include <cmath>

namespace arthrosim::physics {

void ResetBanded(int n, BandedBlockMatrix* a) {
  a->n = n;
  a->diag.resize(n);
  a->sub1.resize(n);
  a->sub2.resize(n);
  a->chain.reserve(n + 1);
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

namespace {

// 3x3 Cholesky by hand (Eigen's generic triangular kernels dominate at this size). Returns the
// smallest pivot (diagonal of L) or -1 if a pivot is not positive.
double Cholesky3(const Mat3& a, Mat3* l) {
  l->setZero();
  const double d0 = a(0, 0);
  if (!(d0 > 0)) return -1;
  const double l00 = std::sqrt(d0);
  const double l10 = a(1, 0) / l00, l20 = a(2, 0) / l00;
  const double d1 = a(1, 1) - l10 * l10;
  if (!(d1 > 0)) return -1;
  const double l11 = std::sqrt(d1);
  const double l21 = (a(2, 1) - l20 * l10) / l11;
  const double d2 = a(2, 2) - l20 * l20 - l21 * l21;
  if (!(d2 > 0)) return -1;
  const double l22 = std::sqrt(d2);
  (*l)(0, 0) = l00;
  (*l)(1, 0) = l10;
  (*l)(2, 0) = l20;
  (*l)(1, 1) = l11;
  (*l)(2, 1) = l21;
  (*l)(2, 2) = l22;
  // The unused upper triangle keeps the reciprocals of the pivots (divisions are slow).
  (*l)(0, 1) = 1 / l00;
  (*l)(0, 2) = 1 / l11;
  (*l)(1, 2) = 1 / l22;
  return std::min({l00, l11, l22});
}

// Solves L y = b (L lower triangular 3x3 from Cholesky3, reciprocal pivots above).
Vec3 Forward3(const Mat3& l, const Vec3& b) {
  const double y0 = b(0) * l(0, 1);
  const double y1 = (b(1) - l(1, 0) * y0) * l(0, 2);
  const double y2 = (b(2) - l(2, 0) * y0 - l(2, 1) * y1) * l(1, 2);
  return Vec3(y0, y1, y2);
}

// Solves L^T x = y.
Vec3 Backward3(const Mat3& l, const Vec3& y) {
  const double x2 = y(2) * l(1, 2);
  const double x1 = (y(1) - l(2, 1) * x2) * l(0, 2);
  const double x0 = (y(0) - l(1, 0) * x1 - l(2, 0) * x2) * l(0, 1);
  return Vec3(x0, x1, x2);
}

// B = A L^-T, row by row (row r of B solves L b = row r of A).
inline void RightSolveLT(const Mat3& l, const Mat3& a, Mat3* b) {
  const double r0 = l(0, 1), r1 = l(0, 2), r2 = l(1, 2);  // reciprocal pivots
  const double l10 = l(1, 0), l20 = l(2, 0), l21 = l(2, 1);
  for (int r = 0; r < 3; ++r) {
    const double y0 = a(r, 0) * r0;
    const double y1 = (a(r, 1) - l10 * y0) * r1;
    const double y2 = (a(r, 2) - l20 * y0 - l21 * y1) * r2;
    (*b)(r, 0) = y0;
    (*b)(r, 1) = y1;
    (*b)(r, 2) = y2;
  }
}

// a(r, .) . b(c, .), summed in the order Eigen 3.4's 3x3 lazy product uses with SSE2 (rows 0-1
// as one packet, row 2 by scalar reduction), so that factors are bit-identical to the Eigen
// products this replaced (any order is equally accurate).
inline double RowDot(const Mat3& a, const Mat3& b, int r, int c) {
  const double x0 = a(r, 0) * b(c, 0), x1 = a(r, 1) * b(c, 1), x2 = a(r, 2) * b(c, 2);
  return r < 2 ? (x0 + x1) + x2 : x0 + (x1 + x2);
}

// Lower triangle of d -= b b^T (Cholesky3 reads only the lower triangle).
inline void SubtractLowerBBt(const Mat3& b, Mat3* d) {
  for (int c = 0; c < 3; ++c)
    for (int r = c; r < 3; ++r) (*d)(r, c) -= RowDot(b, b, r, c);
}

// s -= a b^T.
inline void SubtractABt(const Mat3& a, const Mat3& b, Mat3* s) {
  for (int c = 0; c < 3; ++c)
    for (int r = 0; r < 3; ++r) (*s)(r, c) -= RowDot(a, b, r, c);
}

}  // namespace

namespace {

// Splits the rows into runs that do not couple (zero blocks between them) into a->chain; returns
// the longest run.
int FindChains(BandedBlockMatrix* a) {
  const int n = a->n;
  a->chain.clear();
  int longest = 0;
  for (int i = 0; i < n; ++i) {
    const bool start = i == 0 || (a->sub1[i - 1].isZero(0) && a->sub2[i - 1].isZero(0) &&
                                  (i < 2 || a->sub2[i - 2].isZero(0)));
    if (!start) continue;
    if (i > 0) longest = std::max(longest, i - a->chain.back());
    a->chain.push_back(i);
  }
  if (n > 0) longest = std::max(longest, n - a->chain.back());
  a->chain.push_back(n);
  return longest;
}

}  // namespace

bool FactorBanded(const std::vector<double>& min_pivot, BandedBlockMatrix* a) {
  // Block Cholesky A = L L^T: the same arithmetic as scalar Cholesky, so it stays accurate on
  // a chain whose axial stiffness exceeds its inertia by 1e10 (an explicit D^-1 would not).
  // The Schur complements in diag keep only their lower triangle up to date. Independent runs
  // (threads) go in lock step: a row waits on square roots and divisions of the one before.
  const int longest = FindChains(a);
  const int nc = static_cast<int>(a->chain.size()) - 1;
  for (int q = 0; q < longest; ++q) {
    for (int k = 0; k < nc; ++k) {
      const int i = a->chain[k] + q;
      const int end = a->chain[k + 1];
      if (i >= end) continue;
      Mat3 lii;
      const double piv = Cholesky3(a->diag[i], &lii);  // diag[i] holds the Schur complement
      if (!(piv * piv > min_pivot[i])) return false;
      a->diag[i] = lii;
      Mat3& b1 = a->sub1[i];
      Mat3& b2 = a->sub2[i];
      RightSolveLT(lii, Mat3(b1), &b1);
      RightSolveLT(lii, Mat3(b2), &b2);
      if (i + 1 < end) {
        SubtractLowerBBt(b1, &a->diag[i + 1]);
        if (i + 2 < end) {
          SubtractLowerBBt(b2, &a->diag[i + 2]);
          SubtractABt(b2, b1, &a->sub1[i + 1]);
        }
      }
    }
  }
  return true;
}

namespace {

// Row i of L y = b in a run starting at row `begin`: x(i) from b(i) and the rows above it.
inline void ForwardRow(const BandedBlockMatrix& a, int begin, int i, const double* b, double* x) {
  using Map = Eigen::Map<Vec3>;
  Vec3 y = Eigen::Map<const Vec3>(b + 3 * i);
  if (i - begin >= 1) y -= a.sub1[i - 1] * Map(x + 3 * (i - 1));
  if (i - begin >= 2) y -= a.sub2[i - 2] * Map(x + 3 * (i - 2));
  Map(x + 3 * i) = Forward3(a.diag[i], y);
}

// Row i of L^T x = y in a run ending before row `end`: x(i) from y(i) and the rows below it.
inline void BackwardRow(const BandedBlockMatrix& a, int end, int i, double* x) {
  using Map = Eigen::Map<Vec3>;
  Vec3 z = Map(x + 3 * i);
  if (i + 1 < end) z -= a.sub1[i].transpose() * Map(x + 3 * (i + 1));
  if (i + 2 < end) z -= a.sub2[i].transpose() * Map(x + 3 * (i + 2));
  Map(x + 3 * i) = Backward3(a.diag[i], z);
}

}  // namespace

void SolveBanded(const BandedBlockMatrix& a, const double* b, double* x) {
  const int nc = static_cast<int>(a.chain.size()) - 1;
  int longest = 0;
  for (int k = 0; k < nc; ++k) longest = std::max(longest, a.chain[k + 1] - a.chain[k]);
  for (int q = 0; q < longest; ++q) {  // L y = b
    for (int k = 0; k < nc; ++k) {
      const int i = a.chain[k] + q;
      if (i < a.chain[k + 1]) ForwardRow(a, a.chain[k], i, b, x);
    }
  }
  for (int q = longest - 1; q >= 0; --q) {  // L^T x = y
    for (int k = 0; k < nc; ++k) {
      const int i = a.chain[k] + q;
      if (i < a.chain[k + 1]) BackwardRow(a, a.chain[k + 1], i, x);
    }
  }
}

void SolveBandedSparse(const BandedBlockMatrix& a, const int* rows, int count, double* x) {
  // Touched runs (at most one per row) and the first row of each that is not zero. Rows before
  // it would come out as +0 in SolveBanded (zero minus products with zero), as they are here.
  std::array<int, 4> run{}, first{};
  int touched = 0;
  for (int r = 0; r < count; ++r) {
    const int row = rows[r];
    const int k =
        static_cast<int>(std::upper_bound(a.chain.begin(), a.chain.end(), row) - a.chain.begin()) -
        1;
    int t = 0;
    while (t < touched && run[t] != k) ++t;
    if (t == touched) {
      run[touched] = k;
      first[touched++] = row;
    } else {
      first[t] = std::min(first[t], row);
    }
  }
  for (int t = 0; t < touched; ++t) {
    const int begin = a.chain[run[t]], end = a.chain[run[t] + 1];
    for (int i = first[t]; i < end; ++i) ForwardRow(a, begin, i, x, x);
    for (int i = end - 1; i >= begin; --i) BackwardRow(a, end, i, x);
  }
}

}  // namespace arthrosim::physics
