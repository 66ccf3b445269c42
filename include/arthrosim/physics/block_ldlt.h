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

  /// The same numeric factorisation in parts, for spreading it over several calls: BeginFactor
  /// loads the values (ok() becomes false), then FactorSlice(j, slices) for j = 0, 1, ...,
  /// slices - 1 in that order factors the supernodes of part j (parts of about equal
  /// multiply-add count, a pure function of the pattern). ok() is true after the last part if
  /// the matrix is positive definite. The result is bit for bit that of Factor, whatever the
  /// number of parts. FactorSlice returns false when a part found the matrix not positive
  /// definite (or is called out of order).
  void BeginFactor(std::span<const Mat3> diag, std::span<const Mat3> pair_blocks);
  bool FactorSlice(int slice, int slices);
  /// Parts done since BeginFactor.
  int slices_done() const { return next_slice_; }

  /// x <- A^-1 x in place (3n entries). Valid after a successful Factor.
  void Solve(double* x) const;

  std::int32_t nodes() const { return n_; }
  bool ok() const { return ok_; }
  /// Stored strictly-lower entries of L (fill measure).
  std::int64_t factor_nonzeros() const;

 private:
  void Symbolic();        // L's pattern, supernodes, entry map (after the ordering)
  void SupernodeCosts();  // multiply-adds per supernode (for the parts of FactorSlice)
  std::int64_t SliceBegin(int slice, int slices) const;       // first supernode of a part
  void NumericBegin();                                        // panels from a's values
  bool NumericRange(std::size_t s_begin, std::size_t s_end);  // values of L and D, in order
  struct Impl;
  std::unique_ptr<Impl> impl_;
  std::int32_t n_ = 0;
  bool ok_ = false;
  bool failed_ = false;
  int next_slice_ = 0;
};

}  // namespace arthrosim::physics
