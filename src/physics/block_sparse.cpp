#include "arthrosim/physics/block_sparse.h"

#include <algorithm>

#include "arthrosim/core/parallel.h"

namespace arthrosim::physics {

void BlockSparseMatrix::Reset(std::int32_t n) {
  diag_.assign(static_cast<std::size_t>(n), Mat3::Zero());
  blocks_.clear();
  pairs_.clear();
  refs_.clear();
  free_blocks_.clear();
  row_.assign(static_cast<std::size_t>(n), {});
  live_pairs_ = 0;
  flat_dirty_ = true;
}

void BlockSparseMatrix::Resize(std::int32_t n) {
  if (n <= rows()) return;
  diag_.resize(static_cast<std::size_t>(n), Mat3::Zero());
  row_.resize(static_cast<std::size_t>(n));
  flat_dirty_ = true;
}

std::int32_t BlockSparseMatrix::AddPair(std::int32_t i, std::int32_t j) {
  const std::int32_t r = std::min(i, j);
  const std::int32_t c = std::max(i, j);
  std::vector<Entry>& row = row_[static_cast<std::size_t>(r)];
  auto it = std::lower_bound(row.begin(), row.end(), c,
                             [](const Entry& e, std::int32_t col) { return e.col < col; });
  if (it != row.end() && it->col == c) {
    ++refs_[static_cast<std::size_t>(it->block)];
    return it->block;
  }
  std::int32_t e;
  if (!free_blocks_.empty()) {
    e = free_blocks_.back();
    free_blocks_.pop_back();
    blocks_[static_cast<std::size_t>(e)].setZero();
    pairs_[static_cast<std::size_t>(e)] = {r, c};
    refs_[static_cast<std::size_t>(e)] = 1;
  } else {
    e = static_cast<std::int32_t>(blocks_.size());
    blocks_.push_back(Mat3::Zero());
    pairs_.push_back({r, c});
    refs_.push_back(1);
  }
  row.insert(it, Entry{c, e});
  std::vector<Entry>& other = row_[static_cast<std::size_t>(c)];
  auto jt = std::lower_bound(other.begin(), other.end(), r,
                             [](const Entry& x, std::int32_t col) { return x.col < col; });
  other.insert(jt, Entry{r, e});
  ++live_pairs_;
  flat_dirty_ = true;
  return e;
}

void BlockSparseMatrix::ReleasePair(std::int32_t e) {
  if (--refs_[static_cast<std::size_t>(e)] > 0) return;
  const auto [r, c] = pairs_[static_cast<std::size_t>(e)];
  auto erase = [](std::vector<Entry>& row, std::int32_t col) {
    auto it = std::lower_bound(row.begin(), row.end(), col,
                               [](const Entry& x, std::int32_t k) { return x.col < k; });
    row.erase(it);
  };
  erase(row_[static_cast<std::size_t>(r)], c);
  erase(row_[static_cast<std::size_t>(c)], r);
  pairs_[static_cast<std::size_t>(e)] = {-1, -1};
  free_blocks_.push_back(e);
  --live_pairs_;
  flat_dirty_ = true;
}

void BlockSparseMatrix::SetZero() {
  for (Mat3& m : diag_) m.setZero();
  for (Mat3& m : blocks_) m.setZero();
}

void BlockSparseMatrix::Flatten() const {
  const auto n = static_cast<std::size_t>(rows());
  flat_start_.assign(n + 1, 0);
  flat_col_.clear();
  flat_block_.clear();
  flat_col_.reserve(n + 2 * static_cast<std::size_t>(live_pairs_));
  flat_block_.reserve(flat_col_.capacity());
  for (std::size_t i = 0; i < n; ++i) {
    const auto ii = static_cast<std::int32_t>(i);
    bool diag_done = false;
    for (const Entry& en : row_[i]) {
      if (!diag_done && en.col > ii) {
        flat_col_.push_back(ii);
        flat_block_.push_back(kDiag);
        diag_done = true;
      }
      flat_col_.push_back(en.col);
      flat_block_.push_back(en.col > ii ? en.block : (en.block | kTransposed));
    }
    if (!diag_done) {
      flat_col_.push_back(ii);
      flat_block_.push_back(kDiag);
    }
    flat_start_[i + 1] = static_cast<std::int32_t>(flat_col_.size());
  }
  flat_dirty_ = false;
}

void BlockSparseMatrix::Multiply(const Eigen::VectorXd& x,
                                 const std::vector<std::uint8_t>& row_mask,
                                 Eigen::VectorXd* y) const {
  if (flat_dirty_) Flatten();
  const std::int64_t n = rows();
  const double* xv = x.data();
  double* yv = y->data();
  ParallelFor(n, 256, [&](std::int64_t begin, std::int64_t end) {
    for (std::int64_t i = begin; i < end; ++i) {
      const auto iu = static_cast<std::size_t>(i);
      double* yi = yv + 3 * i;
      if (!row_mask[iu]) {
        yi[0] = yi[1] = yi[2] = 0;
        continue;
      }
      // Sum in column order with the diagonal at its place, so the order is the pattern's.
      double a0 = 0, a1 = 0, a2 = 0;
      for (std::int32_t k = flat_start_[iu]; k < flat_start_[iu + 1]; ++k) {
        const std::int32_t code = flat_block_[static_cast<std::size_t>(k)];
        const double* xc =
            xv + 3 * static_cast<std::int64_t>(flat_col_[static_cast<std::size_t>(k)]);
        // Column-major 3x3: m[r + 3 c]. Row r of B is (m[r], m[r+3], m[r+6]); of B^T, column r.
        if (code == kDiag || !(code & kTransposed)) {
          const double* m =
              (code == kDiag ? diag_[iu] : blocks_[static_cast<std::size_t>(code)]).data();
          a0 += (m[0] * xc[0] + m[3] * xc[1]) + m[6] * xc[2];
          a1 += (m[1] * xc[0] + m[4] * xc[1]) + m[7] * xc[2];
          a2 += (m[2] * xc[0] + m[5] * xc[1]) + m[8] * xc[2];
        } else {
          const double* m = blocks_[static_cast<std::size_t>(code & ~kTransposed)].data();
          a0 += (m[0] * xc[0] + m[1] * xc[1]) + m[2] * xc[2];
          a1 += (m[3] * xc[0] + m[4] * xc[1]) + m[5] * xc[2];
          a2 += (m[6] * xc[0] + m[7] * xc[1]) + m[8] * xc[2];
        }
      }
      yi[0] = a0;
      yi[1] = a1;
      yi[2] = a2;
    }
  });
}

}  // namespace arthrosim::physics
