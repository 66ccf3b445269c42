#include "arthrosim/physics/block_ldlt.h"

#include <Eigen/Cholesky>
#include <Eigen/Sparse>
#include <algorithm>
#include <cmath>

namespace arthrosim::physics {

struct BlockLdlt::Impl {
  Eigen::SparseMatrix<double> a;  // lower triangle (column-major), pattern fixed by Analyze
  std::vector<std::array<std::int32_t, 6>> diag_pos;  // (0,0),(1,0),(2,0),(1,1),(2,1),(2,2)
  std::vector<std::array<std::int32_t, 9>> pair_pos;  // entry (3j+c, 3i+r) holds B(r, c)
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>, Eigen::Lower> ldlt;
  // Solve data copied out of the factor: permutation, 1/D, and L (unit lower) as supernodes:
  // runs of columns [c0, c1) whose below-run rows R are shared, stored as the strictly lower
  // triangle T of the run (column-major, w x w) and the dense panel B = L(R, c0:c1) row-major,
  // so that each row of R is touched once per run instead of once per column.
  std::vector<std::int32_t> perm;
  std::vector<double> inv_d;
  std::vector<std::int32_t> sn_col;  // supernode s: columns [sn_col[s], sn_col[s + 1])
  std::vector<std::int64_t> sn_row;  // rows of s: rows[sn_row[s] .. sn_row[s + 1])
  std::vector<std::int64_t> sn_val;  // values of s: T then B, from sn_val[s]
  std::vector<std::int32_t> rows;
  std::vector<double> vals;
  std::int64_t nnz = 0;
  // Own numeric factorisation (left-looking, supernodal) on the pattern above: per supernode a
  // dense column-major panel of (w + |R|) rows (its triangle, then the rows R) by w columns.
  std::vector<std::int64_t> panel_at;    // supernode s: panel from panel_at[s]
  std::vector<double> cost;              // supernode s: multiply-adds done at s (updates + own)
  std::vector<std::int32_t> sn_of_col;   // column -> supernode
  std::vector<std::int64_t> a_to_panel;  // entry p of a -> its panel position
  std::vector<double> panel, dvals, scaled, sums;
  std::vector<std::int32_t> rel, head, next, cursor;
  mutable std::vector<double> work, acc, gather;
  Eigen::MatrixXd gemm_s, gemm_c;  // scratch of the large supernode updates (grow only)
};

namespace {

// Supernode updates with at least this many multiply-adds go through one dense product.
// Determinism: Eigen's GEMM splits the inner (summed) dimension only beyond its kc block
// (~500 for doubles with a 32 KiB L1); supernode widths here stay far below, so each entry is
// summed in the same order on any x86-64 machine (the split of rows/columns changes nothing).
constexpr std::int64_t kGemmMinWork = 2048;

// Supernodes at least this wide are factored by blocked dense kernels (Cholesky, then a
// triangular solve for the rows below), narrower ones column by column.
constexpr std::int64_t kBlockedMinWidth = 24;

// A sparse pattern by columns: column c's rows are rows[start[c] .. start[c + 1]).
struct ColumnPattern {
  std::vector<int> start, rows;
};

// Where the permutation P takes each index (the identity when P is empty).
template <class Indices>
std::vector<std::int32_t> PermutationOf(const Indices& pidx, Eigen::Index dim) {
  std::vector<std::int32_t> to(static_cast<std::size_t>(dim));
  for (Eigen::Index i = 0; i < dim; ++i)
    to[static_cast<std::size_t>(i)] = pidx.size() ? pidx[i] : static_cast<std::int32_t>(i);
  return to;
}

// The strictly upper pattern of P A P^T by columns (column max(p_r, p_c) holds row
// min(p_r, p_c)), from the stored entries of `a` and the permutation `to`.
ColumnPattern UpperPattern(const Eigen::SparseMatrix<double>& a,
                           const std::vector<std::int32_t>& to) {
  const Eigen::Index dim = a.rows();
  ColumnPattern up;
  up.start.assign(static_cast<std::size_t>(dim) + 1, 0);
  auto each_entry = [&](auto&& visit) {
    for (Eigen::Index c = 0; c < dim; ++c) {
      for (int p = a.outerIndexPtr()[c]; p < a.outerIndexPtr()[c + 1]; ++p) {
        const std::int32_t pr = to[static_cast<std::size_t>(a.innerIndexPtr()[p])];
        const std::int32_t pc = to[static_cast<std::size_t>(c)];
        if (pr != pc) visit(std::max(pr, pc), std::min(pr, pc));
      }
    }
  };
  each_entry([&](int col, int) { ++up.start[static_cast<std::size_t>(col) + 1]; });
  for (Eigen::Index k = 0; k < dim; ++k)
    up.start[static_cast<std::size_t>(k) + 1] += up.start[static_cast<std::size_t>(k)];
  up.rows.resize(static_cast<std::size_t>(up.start[static_cast<std::size_t>(dim)]));
  std::vector<int> fill(up.start.begin(), up.start.end() - 1);
  each_entry([&](int col, int row) {
    up.rows[static_cast<std::size_t>(fill[static_cast<std::size_t>(col)]++)] = row;
  });
  return up;
}

// The pattern of L for the upper pattern `up` by a symbolic up-looking elimination: row k of L
// holds every node met on the elimination-tree paths from the entries (i, k), i < k, up to k;
// each column lists its rows ascending (the order a numeric factorisation appends them).
ColumnPattern PatternOfL(const ColumnPattern& up) {
  const std::size_t dim = up.start.size() - 1;
  std::vector<int> parent(dim, -1), tag(dim);
  auto walk = [&](auto&& visit) {
    std::fill(parent.begin(), parent.end(), -1);
    for (std::size_t k = 0; k < dim; ++k) {
      const int kk = static_cast<int>(k);
      tag[k] = kk;
      for (int p = up.start[k]; p < up.start[k + 1]; ++p) {
        for (int i = up.rows[static_cast<std::size_t>(p)]; tag[static_cast<std::size_t>(i)] != kk;
             i = parent[static_cast<std::size_t>(i)]) {
          if (parent[static_cast<std::size_t>(i)] == -1) parent[static_cast<std::size_t>(i)] = kk;
          visit(i, kk);
          tag[static_cast<std::size_t>(i)] = kk;
        }
      }
    }
  };
  ColumnPattern l;
  l.start.assign(dim + 1, 0);
  walk([&](int i, int) { ++l.start[static_cast<std::size_t>(i) + 1]; });
  for (std::size_t k = 0; k < dim; ++k) l.start[k + 1] += l.start[k];
  l.rows.resize(static_cast<std::size_t>(l.start[dim]));
  std::vector<int> fill(l.start.begin(), l.start.end() - 1);
  walk([&](int i, int k) {
    l.rows[static_cast<std::size_t>(fill[static_cast<std::size_t>(i)]++)] = k;
  });
  return l;
}

// LDL^T of a supernode panel in place (column-major, ld rows: the w x w triangle, then the rows
// below), right-looking column by column; D into d. False when not positive definite.
bool DenseLdlt(double* ps, std::int64_t w, std::int64_t ld, double* d) {
  for (std::int64_t j = 0; j < w; ++j) {
    double* cj = ps + j * ld;
    const double dj = cj[j];
    if (!(dj > 0) || !std::isfinite(dj)) return false;
    d[j] = dj;
    const double inv = 1.0 / dj;
    for (std::int64_t k = j + 1; k < w; ++k) {
      const double lkj_d = cj[k];  // L(k, j) d_j
      double* ck = ps + k * ld;
      for (std::int64_t i = k; i < ld; ++i) ck[i] -= cj[i] * (lkj_d * inv);
    }
    for (std::int64_t i = j + 1; i < ld; ++i) cj[i] *= inv;
  }
  return true;
}

// The same for a wide panel with blocked kernels: Cholesky C C^T of the triangle (Eigen's
// blocked LLT), rows below B <- B C^-T, then L = C diag(C)^-1 and D = diag(C)^2.
bool DenseLdltBlocked(double* ps, std::int64_t w, std::int64_t rc, double* d) {
  using Panel = Eigen::Map<Eigen::MatrixXd, 0, Eigen::OuterStride<>>;
  const std::int64_t ld = w + rc;
  Panel top(ps, w, w, Eigen::OuterStride<>(ld));
  Panel below(ps + w, rc, w, Eigen::OuterStride<>(ld));
  Eigen::Ref<Eigen::MatrixXd, 0, Eigen::OuterStride<>> top_ref(top);
  Eigen::LLT<Eigen::Ref<Eigen::MatrixXd, 0, Eigen::OuterStride<>>, Eigen::Lower> llt(top_ref);
  if (llt.info() != Eigen::Success) return false;
  if (rc > 0) top.triangularView<Eigen::Lower>().transpose().solveInPlace<Eigen::OnTheRight>(below);
  for (std::int64_t j = 0; j < w; ++j) {
    const double cjj = top(j, j);
    if (!(cjj > 0) || !std::isfinite(cjj)) return false;
    d[j] = cjj * cjj;
    const double inv = 1.0 / cjj;
    for (std::int64_t i = j + 1; i < w; ++i) top(i, j) *= inv;
    for (std::int64_t i = 0; i < rc; ++i) below(i, j) *= inv;
  }
  return true;
}

// Dot product of length n in four interleaved partial sums: a single running sum waits on the
// add latency each term (wide supernodes); the order is fixed, so the bits are too.
inline double Dot(const double* a, const double* b, std::size_t n) {
  double s0 = 0, s1 = 0, s2 = 0, s3 = 0;
  std::size_t k = 0;
  for (; k + 4 <= n; k += 4) {
    s0 += a[k] * b[k];
    s1 += a[k + 1] * b[k + 1];
    s2 += a[k + 2] * b[k + 2];
    s3 += a[k + 3] * b[k + 3];
  }
  for (; k < n; ++k) s0 += a[k] * b[k];
  return (s0 + s1) + (s2 + s3);
}

// Below-run rows of one supernode, forward: w[rows[r]] -= B(r, :) y. W > 0: fixed width (the
// compiler keeps y in registers); W = 0: runtime width wd. Same summation order either way.
template <std::size_t W>
void ForwardRows(const double* b, const std::int32_t* rows, std::size_t rc, std::size_t wd,
                 const double* y, double* w) {
  const std::size_t n = W ? W : wd;
  for (std::size_t r = 0; r < rc; ++r) {
    const double* br = b + r * n;
    w[rows[r]] -= Dot(br, y, n);
  }
}

// Backward: acc = B^T x(rows), each acc[k] summed in row order.
template <std::size_t W>
void BackwardRows(const double* b, const std::int32_t* rows, std::size_t rc, std::size_t wd,
                  const double* w, double* acc) {
  const std::size_t n = W ? W : wd;
  for (std::size_t k = 0; k < n; ++k) acc[k] = 0;
  for (std::size_t r = 0; r < rc; ++r) {
    const double xr = w[rows[r]];
    const double* br = b + r * n;
    for (std::size_t k = 0; k < n; ++k) acc[k] += br[k] * xr;
  }
}

}  // namespace

BlockLdlt::BlockLdlt() : impl_(std::make_unique<Impl>()) {}
BlockLdlt::~BlockLdlt() = default;
BlockLdlt::BlockLdlt(BlockLdlt&&) noexcept = default;
BlockLdlt& BlockLdlt::operator=(BlockLdlt&&) noexcept = default;

std::int64_t BlockLdlt::factor_nonzeros() const { return impl_->nnz; }

void BlockLdlt::Analyze(std::int32_t n, std::span<const std::array<std::int32_t, 2>> pairs) {
  Impl& m = *impl_;
  n_ = n;
  ok_ = false;
  failed_ = false;
  next_slice_ = 0;
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
  Symbolic();
}

void BlockLdlt::Symbolic() {
  Impl& m = *impl_;
  const Eigen::Index dim = m.a.rows();
  // The pattern of L (in the ordering analyzePattern chose): what a numeric SimplicialLDLT
  // factorisation stores (its structural entries), without its arithmetic.
  const std::vector<std::int32_t> to = PermutationOf(m.ldlt.permutationP().indices(), dim);
  const ColumnPattern l = PatternOfL(UpperPattern(m.a, to));
  const int* lp = l.start.data();
  const int* li = l.rows.data();
  m.nnz = dim > 0 ? lp[dim] : 0;
  // Fundamental supernodes: column j + 1 continues the run of j when L(j + 1, j) is the first
  // entry of column j and the patterns below agree (equal counts, nested by the elimination
  // tree).
  m.sn_col.clear();
  m.sn_row.assign(1, 0);
  m.sn_val.assign(1, 0);
  m.panel_at.assign(1, 0);
  m.rows.clear();
  m.sn_of_col.assign(static_cast<std::size_t>(dim), 0);
  std::size_t max_w = 1;
  for (Eigen::Index c0 = 0; c0 < dim;) {
    Eigen::Index c1 = c0 + 1;
    while (c1 < dim && lp[c1] - lp[c1 - 1] == lp[c1 + 1] - lp[c1] + 1 && lp[c1] > lp[c1 - 1] &&
           li[lp[c1 - 1]] == c1)
      ++c1;
    const auto w = static_cast<std::size_t>(c1 - c0);
    max_w = std::max(max_w, w);
    for (Eigen::Index c = c0; c < c1; ++c)
      m.sn_of_col[static_cast<std::size_t>(c)] = static_cast<std::int32_t>(m.sn_col.size());
    m.sn_col.push_back(static_cast<std::int32_t>(c0));
    // Rows below the run: the pattern of its last column.
    const int* rb = li + lp[c1 - 1];
    const int* re = li + lp[c1];
    m.rows.insert(m.rows.end(), rb, re);
    const auto rcount = static_cast<std::int64_t>(re - rb);
    const auto wi = static_cast<std::int64_t>(w);
    m.sn_row.push_back(static_cast<std::int64_t>(m.rows.size()));
    m.sn_val.push_back(m.sn_val.back() + wi * wi + rcount * wi);
    m.panel_at.push_back(m.panel_at.back() + (wi + rcount) * wi);
    c0 = c1;
  }
  m.sn_col.push_back(static_cast<std::int32_t>(dim));
  m.acc.assign(max_w, 0.0);
  m.gather.assign(static_cast<std::size_t>(dim), 0.0);
  m.vals.assign(static_cast<std::size_t>(m.sn_val.back()), 0.0);
  m.panel.assign(static_cast<std::size_t>(m.panel_at.back()), 0.0);
  m.inv_d.assign(static_cast<std::size_t>(dim), 0.0);
  m.dvals.assign(static_cast<std::size_t>(dim), 0.0);
  m.scaled.assign(max_w, 0.0);
  std::int64_t max_rc = 1;
  for (std::size_t q = 0; q + 1 < m.sn_row.size(); ++q)
    max_rc = std::max(max_rc, m.sn_row[q + 1] - m.sn_row[q]);
  m.sums.assign(static_cast<std::size_t>(max_rc), 0.0);
  const std::size_t ns = m.sn_col.size() - 1;
  m.head.assign(ns, -1);
  m.next.assign(ns, -1);
  m.cursor.assign(ns, 0);
  m.rel.assign(static_cast<std::size_t>(dim), -1);
  const auto& pp = m.ldlt.permutationP().indices();
  m.perm.resize(static_cast<std::size_t>(dim));
  for (Eigen::Index i = 0; i < dim; ++i)
    m.perm[static_cast<std::size_t>(i)] = pp.size() ? pp[i] : static_cast<std::int32_t>(i);
  // Where each stored entry (r >= c) of A lands: L position (max, min) of the permuted pair.
  m.a_to_panel.assign(static_cast<std::size_t>(m.a.nonZeros()), -1);
  for (Eigen::Index c = 0; c < dim; ++c) {
    for (int p = m.a.outerIndexPtr()[c]; p < m.a.outerIndexPtr()[c + 1]; ++p) {
      const std::int32_t pr = m.perm[static_cast<std::size_t>(m.a.innerIndexPtr()[p])];
      const std::int32_t pc = m.perm[static_cast<std::size_t>(c)];
      const std::int32_t row = std::max(pr, pc), col = std::min(pr, pc);
      const auto sn = static_cast<std::size_t>(m.sn_of_col[static_cast<std::size_t>(col)]);
      const std::int32_t c0 = m.sn_col[sn];
      const std::int64_t w = m.sn_col[sn + 1] - c0;
      const std::int64_t rc = m.sn_row[sn + 1] - m.sn_row[sn];
      std::int64_t i = row - c0;
      if (row >= c0 + w) {
        const std::int32_t* rb = m.rows.data() + m.sn_row[sn];
        i = w + (std::lower_bound(rb, rb + rc, row) - rb);
      }
      m.a_to_panel[static_cast<std::size_t>(p)] = m.panel_at[sn] + (col - c0) * (w + rc) + i;
    }
  }
  SupernodeCosts();
}

void BlockLdlt::SupernodeCosts() {
  // The multiply-adds NumericFactor does at each supernode: the updates it receives (for each
  // source d, its rows grouped by target supernode, as the left-looking loop visits them) and
  // its own dense factorisation. A pure function of the pattern.
  Impl& m = *impl_;
  const std::size_t ns = m.sn_col.size() - 1;
  m.cost.assign(ns, 0.0);
  for (std::size_t d = 0; d < ns; ++d) {
    const auto dw = static_cast<double>(m.sn_col[d + 1] - m.sn_col[d]);
    const std::int32_t* rd = m.rows.data() + m.sn_row[d];
    const std::int64_t drc = m.sn_row[d + 1] - m.sn_row[d];
    m.cost[d] += dw * dw * (dw / 3.0 + static_cast<double>(drc)) + dw;
    for (std::int64_t p0 = 0; p0 < drc;) {
      const std::int32_t t = m.sn_of_col[static_cast<std::size_t>(rd[p0])];
      const std::int32_t end = m.sn_col[static_cast<std::size_t>(t) + 1];
      std::int64_t q = p0;
      while (q < drc && rd[q] < end) ++q;
      m.cost[static_cast<std::size_t>(t)] +=
          dw * static_cast<double>(q - p0) * static_cast<double>(drc - p0);
      p0 = q;
    }
  }
}

std::int64_t BlockLdlt::SliceBegin(int slice, int slices) const {
  // First supernode of slice j: where the running cost reaches j / slices of the total.
  const Impl& m = *impl_;
  const auto ns = static_cast<std::int64_t>(m.cost.size());
  if (slice <= 0) return 0;
  if (slice >= slices) return ns;
  double total = 0;
  for (double c : m.cost) total += c;
  const double target = total * static_cast<double>(slice) / static_cast<double>(slices);
  double run = 0;
  for (std::int64_t s = 0; s < ns; ++s) {
    if (run >= target) return s;
    run += m.cost[static_cast<std::size_t>(s)];
  }
  return ns;
}

void BlockLdlt::NumericBegin() {
  Impl& m = *impl_;
  double* panel = m.panel.data();
  std::fill(m.panel.begin(), m.panel.end(), 0.0);
  const double* v = m.a.valuePtr();
  for (std::size_t p = 0; p < m.a_to_panel.size(); ++p) panel[m.a_to_panel[p]] = v[p];
  std::fill(m.head.begin(), m.head.end(), -1);
}

bool BlockLdlt::NumericRange(std::size_t s_begin, std::size_t s_end) {
  Impl& m = *impl_;
  double* panel = m.panel.data();
  std::int32_t* rel = m.rel.data();
  double* scaled = m.scaled.data();
  for (std::size_t s = s_begin; s < s_end; ++s) {
    const std::int32_t c0 = m.sn_col[s];
    const std::int64_t w = m.sn_col[s + 1] - c0;
    const std::int32_t* rs = m.rows.data() + m.sn_row[s];
    const std::int64_t rc = m.sn_row[s + 1] - m.sn_row[s];
    const std::int64_t ld = w + rc;
    double* ps = panel + m.panel_at[s];
    for (std::int64_t r = 0; r < rc; ++r) rel[rs[r]] = static_cast<std::int32_t>(w + r);
    // Updates from the supernodes d whose rows reach into [c0, c0 + w), in list order.
    for (std::int32_t d = m.head[s]; d >= 0;) {
      const auto du = static_cast<std::size_t>(d);
      const std::int32_t dnext = m.next[du];
      const std::int32_t dc0 = m.sn_col[du];
      const std::int64_t dw = m.sn_col[du + 1] - dc0;
      const std::int32_t* rd = m.rows.data() + m.sn_row[du];
      const std::int64_t drc = m.sn_row[du + 1] - m.sn_row[du];
      const std::int64_t dld = dw + drc;
      const double* pd = panel + m.panel_at[du];
      const std::int64_t p0 = m.cursor[du];
      std::int64_t q = p0;
      while (q < drc && rd[q] < c0 + w) ++q;
      const std::int64_t nj = q - p0, ni = drc - p0;
      if (dw * nj * ni >= kGemmMinWork) {
        // Large update: C = L_d(p0:, :) D_d L_d(p0:q, :)^T as one dense product (register
        // blocked), then scattered into the target columns' lower parts.
        using Panel = Eigen::Map<const Eigen::MatrixXd, 0, Eigen::OuterStride<>>;
        const Panel ld_rows(pd + dw + p0, ni, dw, Eigen::OuterStride<>(dld));
        m.gemm_s.resize(nj, dw);
        m.gemm_s.noalias() =
            ld_rows.topRows(nj) *
            Eigen::Map<const Eigen::VectorXd>(m.dvals.data() + dc0, dw).asDiagonal();
        m.gemm_c.resize(ni, nj);
        m.gemm_c.noalias() = ld_rows * m.gemm_s.transpose();
        for (std::int64_t jj = 0; jj < nj; ++jj) {
          double* col = ps + (rd[p0 + jj] - c0) * ld;
          const double* cj = m.gemm_c.data() + jj * ni;
          for (std::int64_t ii = jj; ii < ni; ++ii) {
            const std::int32_t row = rd[p0 + ii];
            col[row < c0 + w ? row - c0 : rel[row]] -= cj[ii];
          }
        }
      } else {
        // For each target column j (row rd[j] of d, inside s): scaled = D_d L_d(j, :), then
        // subtract L_d(i, :) . scaled from every row i >= j of d.
        for (std::int64_t j = p0; j < q; ++j) {
          for (std::int64_t k = 0; k < dw; ++k)
            scaled[k] = pd[k * dld + dw + j] * m.dvals[static_cast<std::size_t>(dc0 + k)];
          // Column sweeps over d's contiguous panel columns (vectorisable), then one scatter.
          double* sum = m.sums.data();
          for (std::int64_t i = j; i < drc; ++i) sum[i] = 0;
          for (std::int64_t k = 0; k < dw; ++k) {
            const double* lk = pd + k * dld + dw;
            const double sk = scaled[k];
            for (std::int64_t i = j; i < drc; ++i) sum[i] += lk[i] * sk;
          }
          double* col = ps + (rd[j] - c0) * ld;
          for (std::int64_t i = j; i < drc; ++i) {
            const std::int32_t row = rd[i];
            col[row < c0 + w ? row - c0 : rel[row]] -= sum[i];
          }
        }
      }
      m.cursor[du] = static_cast<std::int32_t>(q);
      if (q < drc) {  // on to the supernode of its next row
        const auto t = static_cast<std::size_t>(m.sn_of_col[static_cast<std::size_t>(rd[q])]);
        m.next[du] = m.head[t];
        m.head[t] = d;
      }
      d = dnext;
    }
    if (w >= kBlockedMinWidth) {
      if (!DenseLdltBlocked(ps, w, rc, m.dvals.data() + c0)) return false;
    } else if (!DenseLdlt(ps, w, ld, m.dvals.data() + c0)) {
      return false;
    }
    m.cursor[s] = 0;
    if (rc > 0) {
      const auto t = static_cast<std::size_t>(m.sn_of_col[static_cast<std::size_t>(rs[0])]);
      m.next[s] = m.head[t];
      m.head[t] = static_cast<std::int32_t>(s);
    }
    // Solve layout: T(i, k) at t[k w + i], B(r, k) at b[r w + k].
    double* t = m.vals.data() + m.sn_val[s];
    double* b = t + w * w;
    for (std::int64_t k = 0; k < w; ++k) {
      for (std::int64_t i = k + 1; i < w; ++i) t[k * w + i] = ps[k * ld + i];
      for (std::int64_t r = 0; r < rc; ++r) b[r * w + k] = ps[k * ld + w + r];
    }
  }
  if (s_end + 1 == m.sn_col.size()) {
    for (std::size_t i = 0; i < m.dvals.size(); ++i) m.inv_d[i] = 1.0 / m.dvals[i];
  }
  return true;
}

bool BlockLdlt::Factor(std::span<const Mat3> diag, std::span<const Mat3> pair_blocks) {
  BeginFactor(diag, pair_blocks);
  return FactorSlice(0, 1);
}

bool BlockLdlt::FactorSlice(int slice, int slices) {
  if (slice != next_slice_ || slice >= slices) return false;  // out of order: refuse
  const auto b = static_cast<std::size_t>(SliceBegin(slice, slices));
  const auto e = static_cast<std::size_t>(SliceBegin(slice + 1, slices));
  failed_ = failed_ || !NumericRange(b, e);
  ++next_slice_;
  ok_ = !failed_ && next_slice_ == slices;
  return !failed_;
}

void BlockLdlt::BeginFactor(std::span<const Mat3> diag, std::span<const Mat3> pair_blocks) {
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
  ok_ = false;
  failed_ = false;
  next_slice_ = 0;
  NumericBegin();
}

void BlockLdlt::Solve(double* x) const {
  const Impl& m = *impl_;
  const std::size_t dim = m.perm.size();
  double* w = m.work.data();
  double* acc = m.acc.data();
  const std::int32_t* perm = m.perm.data();
  for (std::size_t i = 0; i < dim; ++i) w[perm[i]] = x[i];
  const std::size_t ns = m.sn_col.size() - 1;
  // L y = b: per run, the small unit triangle, then each below row once: w_r -= B(r, :) y.
  for (std::size_t s = 0; s < ns; ++s) {
    const std::int32_t c0 = m.sn_col[s];
    const auto wd = static_cast<std::size_t>(m.sn_col[s + 1] - c0);
    const double* t = m.vals.data() + m.sn_val[s];
    const double* b = t + wd * wd;
    double* y = w + c0;
    for (std::size_t k = 0; k < wd; ++k) {
      const double yk = y[k];
      for (std::size_t i = k + 1; i < wd; ++i) y[i] -= t[k * wd + i] * yk;
    }
    const std::int32_t* rows = m.rows.data() + m.sn_row[s];
    const auto rc = static_cast<std::size_t>(m.sn_row[s + 1] - m.sn_row[s]);
    switch (wd) {
      case 3:
        ForwardRows<3>(b, rows, rc, wd, y, w);
        break;
      case 6:
        ForwardRows<6>(b, rows, rc, wd, y, w);
        break;
      default: {
        // Wide runs: one dense product g = B y (Eigen's GEMV, fixed order for a given build),
        // then one scatter.
        using RowMajor = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
        const Eigen::Map<const RowMajor> bm(b, static_cast<Eigen::Index>(rc),
                                            static_cast<Eigen::Index>(wd));
        Eigen::Map<Eigen::VectorXd> g(m.gather.data(), static_cast<Eigen::Index>(rc));
        g.noalias() = bm * Eigen::Map<const Eigen::VectorXd>(y, static_cast<Eigen::Index>(wd));
        for (std::size_t r = 0; r < rc; ++r) w[rows[r]] -= m.gather[r];
        break;
      }
    }
  }
  for (std::size_t j = 0; j < dim; ++j) w[j] *= m.inv_d[j];
  // L^T x = y: per run backwards, gather the below rows (acc = B^T x_R), then the triangle.
  for (std::size_t s = ns; s-- > 0;) {
    const std::int32_t c0 = m.sn_col[s];
    const auto wd = static_cast<std::size_t>(m.sn_col[s + 1] - c0);
    const double* t = m.vals.data() + m.sn_val[s];
    const double* b = t + wd * wd;
    double* y = w + c0;
    const std::int32_t* rows = m.rows.data() + m.sn_row[s];
    const auto rc = static_cast<std::size_t>(m.sn_row[s + 1] - m.sn_row[s]);
    switch (wd) {
      case 3:
        BackwardRows<3>(b, rows, rc, wd, w, acc);
        break;
      case 6:
        BackwardRows<6>(b, rows, rc, wd, w, acc);
        break;
      default: {
        using RowMajor = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
        const Eigen::Map<const RowMajor> bm(b, static_cast<Eigen::Index>(rc),
                                            static_cast<Eigen::Index>(wd));
        for (std::size_t r = 0; r < rc; ++r) m.gather[r] = w[rows[r]];
        Eigen::Map<Eigen::VectorXd>(acc, static_cast<Eigen::Index>(wd)).noalias() =
            bm.transpose() *
            Eigen::Map<const Eigen::VectorXd>(m.gather.data(), static_cast<Eigen::Index>(rc));
        break;
      }
    }
    for (std::size_t k = wd; k-- > 0;) {
      y[k] = (y[k] - acc[k]) - Dot(t + k * wd + k + 1, y + k + 1, wd - k - 1);
    }
  }
  for (std::size_t i = 0; i < dim; ++i) x[i] = w[perm[i]];
}

}  // namespace arthrosim::physics
