#include "arthrosim/physics/block_ldlt.h"

#include <Eigen/Sparse>
#include <algorithm>

namespace arthrosim::physics {

struct BlockLdlt::Impl {
  Eigen::SparseMatrix<double> a;  // lower triangle (column-major), pattern fixed by Analyze
  std::vector<std::array<std::int32_t, 6>> diag_pos;  // (0,0),(1,0),(2,0),(1,1),(2,1),(2,2)
  std::vector<std::array<std::int32_t, 9>> pair_pos;  // entry (3j+c, 3i+r) holds B(r, c)
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>, Eigen::Lower> ldlt;
  // Solve data copied out of the factor: permutation, 1/D, L (CSC, strictly lower).
  std::vector<std::int32_t> perm;
  std::vector<double> inv_d;
  std::vector<std::int32_t> lp, li;
  std::vector<double> lx;
  mutable std::vector<double> work;
};

BlockLdlt::BlockLdlt() : impl_(std::make_unique<Impl>()) {}
BlockLdlt::~BlockLdlt() = default;
BlockLdlt::BlockLdlt(BlockLdlt&&) noexcept = default;
BlockLdlt& BlockLdlt::operator=(BlockLdlt&&) noexcept = default;

std::int64_t BlockLdlt::factor_nonzeros() const {
  return static_cast<std::int64_t>(impl_->lx.size());
}

void BlockLdlt::Analyze(std::int32_t n, std::span<const std::array<std::int32_t, 2>> pairs) {
  Impl& m = *impl_;
  n_ = n;
  ok_ = false;
  const Eigen::Index dim = 3 * static_cast<Eigen::Index>(n);
  std::vector<Eigen::Triplet<double>> trip;
  trip.reserve(static_cast<std::size_t>(6 * n) + 9 * pairs.size());
  for (std::int32_t i = 0; i < n; ++i) {
    for (int c = 0; c < 3; ++c)
      for (int r = c; r < 3; ++r) trip.emplace_back(3 * i + r, 3 * i + c, 0.0);
  }
  for (const auto& p : pairs) {
    if (p[0] < 0) continue;
    for (int c = 0; c < 3; ++c)
      for (int r = 0; r < 3; ++r) trip.emplace_back(3 * p[1] + c, 3 * p[0] + r, 0.0);
  }
  m.a.resize(dim, dim);
  m.a.setFromTriplets(trip.begin(), trip.end());
  m.a.makeCompressed();
  auto pos = [&](Eigen::Index row, Eigen::Index col) {
    const int* begin = m.a.innerIndexPtr() + m.a.outerIndexPtr()[col];
    const int* end = m.a.innerIndexPtr() + m.a.outerIndexPtr()[col + 1];
    return static_cast<std::int32_t>(std::lower_bound(begin, end, static_cast<int>(row)) -
                                     m.a.innerIndexPtr());
  };
  m.diag_pos.assign(static_cast<std::size_t>(n), {});
  for (std::int32_t i = 0; i < n; ++i) {
    int k = 0;
    for (int c = 0; c < 3; ++c)
      for (int r = c; r < 3; ++r)
        m.diag_pos[static_cast<std::size_t>(i)][k++] = pos(3 * i + r, 3 * i + c);
  }
  m.pair_pos.assign(pairs.size(), {});
  for (std::size_t e = 0; e < pairs.size(); ++e) {
    const auto& p = pairs[e];
    if (p[0] < 0) continue;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) m.pair_pos[e][3 * r + c] = pos(3 * p[1] + c, 3 * p[0] + r);
  }
  m.ldlt.analyzePattern(m.a);
  m.work.assign(static_cast<std::size_t>(dim), 0.0);
}

bool BlockLdlt::Factor(std::span<const Mat3> diag, std::span<const Mat3> pair_blocks) {
  Impl& m = *impl_;
  double* v = m.a.valuePtr();
  for (std::int32_t i = 0; i < n_; ++i) {
    const Mat3& d = diag[static_cast<std::size_t>(i)];
    const auto& q = m.diag_pos[static_cast<std::size_t>(i)];
    int k = 0;
    for (int c = 0; c < 3; ++c)
      for (int r = c; r < 3; ++r) v[q[k++]] = d(r, c);
  }
  for (std::size_t e = 0; e < m.pair_pos.size() && e < pair_blocks.size(); ++e) {
    const auto& q = m.pair_pos[e];
    if (q[0] == q[1]) continue;  // unused pair (positions left zero)
    const Mat3& b = pair_blocks[e];
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) v[q[3 * r + c]] = b(r, c);
  }
  m.ldlt.factorize(m.a);
  ok_ = m.ldlt.info() == Eigen::Success;
  if (!ok_) return false;
  const auto& l = m.ldlt.matrixL().nestedExpression();
  const Eigen::Index dim = m.a.rows();
  m.lp.assign(l.outerIndexPtr(), l.outerIndexPtr() + dim + 1);
  m.li.assign(l.innerIndexPtr(), l.innerIndexPtr() + m.lp.back());
  m.lx.assign(l.valuePtr(), l.valuePtr() + m.lp.back());
  m.inv_d.resize(static_cast<std::size_t>(dim));
  const Eigen::VectorXd& d = m.ldlt.vectorD();
  for (Eigen::Index i = 0; i < dim; ++i) {
    if (!(d[i] > 0)) {
      ok_ = false;
      return false;
    }
    m.inv_d[static_cast<std::size_t>(i)] = 1.0 / d[i];
  }
  const auto& p = m.ldlt.permutationP().indices();
  m.perm.resize(static_cast<std::size_t>(dim));
  for (Eigen::Index i = 0; i < dim; ++i)
    m.perm[static_cast<std::size_t>(i)] = p.size() ? p[i] : static_cast<std::int32_t>(i);
  return true;
}

void BlockLdlt::Solve(double* x) const {
  const Impl& m = *impl_;
  const std::size_t dim = m.perm.size();
  double* w = m.work.data();
  const std::int32_t* perm = m.perm.data();
  for (std::size_t i = 0; i < dim; ++i) w[perm[i]] = x[i];
  const std::int32_t* lp = m.lp.data();
  const std::int32_t* li = m.li.data();
  const double* lx = m.lx.data();
  // L y = b (column oriented), y <- D^-1 y, L^T z = y (row oriented over columns of L).
  for (std::size_t j = 0; j < dim; ++j) {
    const double yj = w[j];
    if (yj == 0) continue;
    for (std::int32_t p = lp[j]; p < lp[j + 1]; ++p) w[li[p]] -= lx[p] * yj;
  }
  for (std::size_t j = 0; j < dim; ++j) w[j] *= m.inv_d[j];
  for (std::size_t j = dim; j-- > 0;) {
    double s = w[j];
    for (std::int32_t p = lp[j]; p < lp[j + 1]; ++p) s -= lx[p] * w[li[p]];
    w[j] = s;
  }
  for (std::size_t i = 0; i < dim; ++i) x[i] = w[perm[i]];
}

}  // namespace arthrosim::physics
