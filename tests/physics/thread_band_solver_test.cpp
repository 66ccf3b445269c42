// Block-banded Cholesky of the thread solver: the sparse right-hand-side solve used for the
// off-band columns gives the bits of the full solve.
#include "arthrosim/physics/thread_band_solver.h"

#include <gtest/gtest.h>

#include <cstring>
#include <random>
#include <vector>

namespace arthrosim::physics {
namespace {

// Three runs that do not couple: rows 0-4, row 5 alone (a fixed node), rows 6-11. Blocks are
// random with a dominant diagonal, so the matrix is symmetric positive definite.
BandedBlockMatrix ThreeRuns(std::mt19937* rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  auto random = [&]() {
    Mat3 m;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) m(r, c) = u(*rng);
    return m;
  };
  BandedBlockMatrix a;
  ResetBanded(12, &a);
  const std::vector<int> run_end = {5, 6, 12};
  auto same_run = [&](int i, int j) {
    for (int e : run_end)
      if ((i < e) != (j < e)) return false;
    return true;
  };
  for (int i = 0; i < 12; ++i) {
    const Mat3 d = random();
    a.diag[i] = d * d.transpose() + 20.0 * Mat3::Identity();
    if (i + 1 < 12 && same_run(i, i + 1)) a.sub1[i] = random();
    if (i + 2 < 12 && same_run(i, i + 2)) a.sub2[i] = random();
  }
  return a;
}

TEST(ThreadBandSolver, SparseRightHandSideGivesTheBitsOfTheFullSolve) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const BandedBlockMatrix original = ThreeRuns(&rng);
  BandedBlockMatrix a = original;
  const std::vector<double> min_pivot(12, 1e-12);
  ASSERT_TRUE(FactorBanded(min_pivot, &a));
  ASSERT_EQ(a.chain, (std::vector<int>{0, 5, 6, 12}));
  const std::vector<std::vector<int>> cases = {
      {0}, {3}, {5}, {11}, {7, 2}, {9, 9}, {4, 6, 10}, {1, 5, 8, 3}, {11, 6, 0, 5}};
  for (const std::vector<int>& rows : cases) {
    std::vector<double> b(36, 0.0);
    for (int row : rows)
      for (int c = 0; c < 3; ++c) b[3 * row + c] += u(rng);
    std::vector<double> full(36), sparse = b;
    SolveBanded(a, b.data(), full.data());
    SolveBandedSparse(a, rows.data(), static_cast<int>(rows.size()), sparse.data());
    EXPECT_EQ(std::memcmp(full.data(), sparse.data(), sizeof(double) * 36), 0) << rows[0];
    // And it solves the system: A x = b, A from its blocks.
    for (int i = 0; i < 12; ++i) {
      Vec3 ax = original.diag[i] * Eigen::Map<const Vec3>(sparse.data() + 3 * i);
      if (i >= 1) ax += original.sub1[i - 1] * Eigen::Map<const Vec3>(sparse.data() + 3 * (i - 1));
      if (i >= 2) ax += original.sub2[i - 2] * Eigen::Map<const Vec3>(sparse.data() + 3 * (i - 2));
      if (i + 1 < 12)
        ax += original.sub1[i].transpose() * Eigen::Map<const Vec3>(sparse.data() + 3 * (i + 1));
      if (i + 2 < 12)
        ax += original.sub2[i].transpose() * Eigen::Map<const Vec3>(sparse.data() + 3 * (i + 2));
      EXPECT_LT((ax - Eigen::Map<const Vec3>(b.data() + 3 * i)).norm(), 1e-12) << i;
    }
  }
}

}  // namespace
}  // namespace arthrosim::physics
