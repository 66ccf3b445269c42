#pragma once
// Symmetric block-pentadiagonal solver for suture chains: 3x3 blocks, block bandwidth 2 (node i
// couples to i +- 1 through stretch and to i +- 2 through bending). LDL^T without pivoting in
// O(n) time and in buffers sized once, so a steady-state step does not allocate.
// (Block Cholesky A = L L^T; the name of the fields refers to the lower band.)
#include <vector>

#include "arthrosim/core/types.h"

namespace arthrosim::physics {

/// Lower half of a symmetric block matrix with block bandwidth 2, and its LDL^T factors.
struct BandedBlockMatrix {
  int n = 0;               ///< number of 3x3 block rows (nodes)
  std::vector<Mat3> diag;  ///< A(i, i); after Factor: L(i, i) below, 1 / pivots above
  std::vector<Mat3> sub1;  ///< A(i + 1, i); after Factor: L(i + 1, i)
  std::vector<Mat3> sub2;  ///< A(i + 2, i); after Factor: L(i + 2, i)
  /// After Factor: first row of each run of rows that couples to no earlier row (a thread,
  /// fixed nodes alone), then n. The runs are factored and solved in lock step.
  std::vector<int> chain;
};

/// Sets the size to n blocks and zeroes all blocks (no allocation when n is unchanged or smaller
/// than any size used before).
void ResetBanded(int n, BandedBlockMatrix* a);

/// Adds the 3x3 block h at (row, col), |row - col| <= 2, to the lower half (the upper half is
/// implied by symmetry; (row, col) and (col, row) are the same entry).
void AddBandedBlock(int row, int col, const Mat3& h, BandedBlockMatrix* a);

/// Factors A = L L^T in place. Returns false (matrix unusable) if a pivot block is not
/// positive definite with its smallest Cholesky pivot^2 above min_pivot[i] (same units as A).
bool FactorBanded(const std::vector<double>& min_pivot, BandedBlockMatrix* a);

/// Solves A x = b with the factors from FactorBanded; b and x are 3 n long and may alias.
void SolveBanded(const BandedBlockMatrix& a, const double* b, double* x);

/// SolveBanded in place for a right-hand side x that is zero except in the block rows `rows`
/// (count <= 4; any order, repeats allowed): runs that hold none of them stay zero and each
/// other run's forward sweep starts at the first of them. The same bits as SolveBanded(a, x, x).
void SolveBandedSparse(const BandedBlockMatrix& a, const int* rows, int count, double* x);

}  // namespace arthrosim::physics
