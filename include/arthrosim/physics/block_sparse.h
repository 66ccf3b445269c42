#pragma once
// Symmetric 3x3 block-sparse matrix with an incrementally maintained pattern. Off-diagonal
// blocks are stored once per node pair (row < col) with a reference count (the number of
// elements using the pair), so elements can be added and removed at a cost proportional to
// the touched elements. Each row keeps its neighbours sorted by column, so a product sums in
// an order fixed by the pattern alone (not by the history of insertions): results are
// bit-identical to those of a pattern built from scratch.
#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "arthrosim/core/types.h"

namespace arthrosim::physics {

class BlockSparseMatrix {
 public:
  /// Empty pattern with n block rows (n nodes, 3n scalar rows).
  void Reset(std::int32_t n);
  /// Grows (or keeps) the number of block rows; existing blocks are kept.
  void Resize(std::int32_t n);
  std::int32_t rows() const { return static_cast<std::int32_t>(diag_.size()); }

  /// Adds a reference to the block of pair (i, j), i != j, creating it if needed; returns its
  /// index. The block stores the (min, max) orientation.
  std::int32_t AddPair(std::int32_t i, std::int32_t j);
  /// Drops one reference of block e; the pair leaves the pattern when none is left.
  void ReleasePair(std::int32_t e);

  /// Sets every stored value to zero (pattern unchanged).
  void SetZero();
  Mat3& diag(std::int32_t i) { return diag_[static_cast<std::size_t>(i)]; }
  const Mat3& diag(std::int32_t i) const { return diag_[static_cast<std::size_t>(i)]; }
  /// Block of pair e in (row, col) = (min, max) orientation.
  Mat3& block(std::int32_t e) { return blocks_[static_cast<std::size_t>(e)]; }
  std::int32_t block_row(std::int32_t e) const { return pairs_[static_cast<std::size_t>(e)][0]; }
  std::int32_t block_col(std::int32_t e) const { return pairs_[static_cast<std::size_t>(e)][1]; }
  /// Number of pair storage slots (live or recycled): valid block indices are below it.
  std::int32_t block_capacity() const { return static_cast<std::int32_t>(pairs_.size()); }
  /// True when block index e holds a live pair.
  bool block_live(std::int32_t e) const { return pairs_[static_cast<std::size_t>(e)][0] >= 0; }
  /// Number of live off-diagonal pairs.
  std::int64_t pair_count() const { return live_pairs_; }

  /// y = A x for the rows with row_mask[i] != 0 (others set to 0). x, y have 3 * rows() entries.
  /// Rows are independent, so they may be split across threads.
  void Multiply(const Eigen::VectorXd& x, const std::vector<std::uint8_t>& row_mask,
                Eigen::VectorXd* y) const;

 private:
  struct Entry {
    std::int32_t col;
    std::int32_t block;
  };
  std::vector<Mat3> diag_;
  std::vector<Mat3> blocks_;
  std::vector<std::array<std::int32_t, 2>> pairs_;
  std::vector<std::int32_t> refs_;
  std::vector<std::int32_t> free_blocks_;  // recycled block slots (storage only, not order)
  std::vector<std::vector<Entry>> row_;    // sorted by col
  std::int64_t live_pairs_ = 0;
  // Flat copy of the pattern for products (rebuilt after a pattern change): per row its
  // entries in column order, the diagonal at its place. kDiag marks the diagonal; a block
  // index with kTransposed set is read transposed (the row is the pair's larger node).
  static constexpr std::int32_t kDiag = -1;
  static constexpr std::int32_t kTransposed = std::int32_t{1} << 30;
  void Flatten() const;
  mutable bool flat_dirty_ = true;
  mutable std::vector<std::int32_t> flat_start_, flat_col_, flat_block_;
};

}  // namespace arthrosim::physics
