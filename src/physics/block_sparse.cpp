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
}

void BlockSparseMatrix::Resize(std::int32_t n) {
  if (n <= rows()) return;
  diag_.resize(static_cast<std::size_t>(n), Mat3::Zero());
  row_.resize(static_cast<std::size_t>(n));
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
}

void BlockSparseMatrix::SetZero() {
  for (Mat3& m : diag_) m.setZero();
  for (Mat3& m : blocks_) m.setZero();
}

void BlockSparseMatrix::Multiply(const Eigen::VectorXd& x,
                                 const std::vector<std::uint8_t>& row_mask,
                                 Eigen::VectorXd* y) const {
  const std::int64_t n = rows();
  ParallelFor(n, 256, [&](std::int64_t begin, std::int64_t end) {
    for (std::int64_t i = begin; i < end; ++i) {
      auto yi = y->segment<3>(3 * i);
      if (!row_mask[static_cast<std::size_t>(i)]) {
        yi.setZero();
        continue;
      }
      // Sum in column order with the diagonal at its place, so the order is the pattern's.
      Vec3 acc = Vec3::Zero();
      bool diag_done = false;
      for (const Entry& en : row_[static_cast<std::size_t>(i)]) {
        if (!diag_done && en.col > i) {
          acc += diag_[static_cast<std::size_t>(i)] * x.segment<3>(3 * i);
          diag_done = true;
        }
        const Mat3& b = blocks_[static_cast<std::size_t>(en.block)];
        if (en.col > i) {
          acc += b * x.segment<3>(3 * static_cast<std::int64_t>(en.col));
        } else {
          acc += b.transpose() * x.segment<3>(3 * static_cast<std::int64_t>(en.col));
        }
      }
      if (!diag_done) acc += diag_[static_cast<std::size_t>(i)] * x.segment<3>(3 * i);
      yi = acc;
    }
  });
}

}  // namespace arthrosim::physics
