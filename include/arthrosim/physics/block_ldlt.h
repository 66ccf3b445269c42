#pragma once
// Sparse LDL^T factorisation of a symmetric positive-definite matrix made of 3x3 node blocks,
// with the pattern analysed once (fill-reducing ordering, elimination tree) and refactored with
// new values at the cost of the numeric factorisation only. The triangular solves run over the
// factor's arrays in a fixed order: the result is a pure function of the values.
#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "arthrosim/core/types.h"

namespace arthrosim::physics {

class BlockLdlt {
 public:
  BlockLdlt();
  ~BlockLdlt();
  BlockLdlt(BlockLdlt&&) noexcept;
  BlockLdlt& operator=(BlockLdlt&&) noexcept;

  /// Pattern of n nodes (3n unknowns): the diagonal blocks plus the off-diagonal node pairs
  /// `pairs[e] = {i, j}` (i < j, both in [0, n)); entries {-1, -1} are ignored. Orders the
  /// unknowns and analyses the elimination tree (~ms for a few thousand nodes).
  void Analyze(std::int32_t n, std::span<const std::array<std::int32_t, 2>> pairs);

  /// Numeric factorisation with diagonal blocks diag[i] (symmetric) and the (i, j) blocks of
  /// the analysed pairs, pair_blocks[e] (same indexing as Analyze). Returns false when the
  /// matrix is not positive definite in floating point.
  bool Factor(std::span<const Mat3> diag, std::span<const Mat3> pair_blocks);

  /// x <- A^-1 x in place (3n entries). Valid after a successful Factor.
  void Solve(double* x) const;

  std::int32_t nodes() const { return n_; }
  bool ok() const { return ok_; }
  /// Stored strictly-lower entries of L (fill measure).
  std::int64_t factor_nonzeros() const;

 private:
  void Symbolic();       // L's pattern, supernodes, entry map (after the ordering)
  bool NumericFactor();  // values of L and D from a's values
  struct Impl;
  std::unique_ptr<Impl> impl_;
  std::int32_t n_ = 0;
  bool ok_ = false;
};

}  // namespace arthrosim::physics
