#include "arthrosim/mesh/surface_tissue.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

namespace arthrosim::mesh {
namespace {

Vec3 Centroid(const Points& nodes, const Tri& t) {
  return (nodes.col(t[0]) + nodes.col(t[1]) + nodes.col(t[2])) / 3.0;
}

// Uniform grid over the initial centroids for the nearest-centroid queries of appended triangles.
class CentroidGrid {
 public:
  CentroidGrid(const TriMesh& initial, double cell_mm) : cell_(cell_mm) {
    centroids_.reserve(initial.tris.size());
    for (const Tri& t : initial.tris) centroids_.push_back(Centroid(initial.nodes, t));
    lo_ = hi_ = centroids_.front();
    for (const Vec3& c : centroids_) {
      lo_ = lo_.cwiseMin(c);
      hi_ = hi_.cwiseMax(c);
    }
    for (int k = 0; k < 3; ++k)
      n_[k] = std::max(1, static_cast<int>(std::floor((hi_[k] - lo_[k]) / cell_)) + 1);
    start_.assign(static_cast<std::size_t>(n_[0]) * n_[1] * n_[2] + 1, 0);
    std::vector<std::size_t> cell_of(centroids_.size());
    for (std::size_t i = 0; i < centroids_.size(); ++i) {
      cell_of[i] = Flat(Cell(centroids_[i]));
      ++start_[cell_of[i] + 1];
    }
    for (std::size_t c = 1; c < start_.size(); ++c) start_[c] += start_[c - 1];
    items_.resize(centroids_.size());
    std::vector<std::size_t> fill(start_.begin(), start_.end() - 1);
    for (std::size_t i = 0; i < centroids_.size(); ++i)  // ascending within each cell
      items_[fill[cell_of[i]]++] = static_cast<std::int32_t>(i);
  }

  // Index of the centroid nearest to p (ties: lowest index).
  std::int32_t Nearest(const Vec3& p) const {
    const std::array<int, 3> c = Cell(p);
    double best = std::numeric_limits<double>::infinity();
    std::int32_t best_i = 0;
    const int max_ring = std::max({n_[0], n_[1], n_[2]});
    for (int ring = 0; ring <= max_ring; ++ring) {
      // every centroid in a cell of Chebyshev ring r is at least (r - 1) cells from p
      if (ring > 0 && std::isfinite(best)) {
        const double reach = (ring - 1) * cell_;
        if (reach * reach > best) break;
      }
      for (int x = c[0] - ring; x <= c[0] + ring; ++x) {
        for (int y = c[1] - ring; y <= c[1] + ring; ++y) {
          for (int z = c[2] - ring; z <= c[2] + ring; ++z) {
            if (std::max({std::abs(x - c[0]), std::abs(y - c[1]), std::abs(z - c[2])}) != ring)
              continue;
            if (x < 0 || y < 0 || z < 0 || x >= n_[0] || y >= n_[1] || z >= n_[2]) continue;
            const std::size_t f = Flat({x, y, z});
            for (std::size_t k = start_[f]; k < start_[f + 1]; ++k) {
              const std::int32_t i = items_[k];
              const double d2 = (centroids_[static_cast<std::size_t>(i)] - p).squaredNorm();
              if (d2 < best || (d2 == best && i < best_i)) {
                best = d2;
                best_i = i;
              }
            }
          }
        }
      }
    }
    return best_i;
  }

 private:
  std::array<int, 3> Cell(const Vec3& p) const {
    std::array<int, 3> c{};
    for (int k = 0; k < 3; ++k) {
      const double f = std::floor((p[k] - lo_[k]) / cell_);
      c[k] = static_cast<int>(std::clamp(f, 0.0, static_cast<double>(n_[k] - 1)));
    }
    return c;
  }
  std::size_t Flat(const std::array<int, 3>& c) const {
    return (static_cast<std::size_t>(c[0]) * n_[1] + c[1]) * n_[2] + c[2];
  }

  double cell_;
  std::vector<Vec3> centroids_;
  Vec3 lo_ = Vec3::Zero(), hi_ = Vec3::Zero();
  std::array<int, 3> n_{1, 1, 1};
  std::vector<std::size_t> start_;
  std::vector<std::int32_t> items_;
};

// Grid cell edge, mm: a few bone triangles (1-2.5 mm edges) per cell.
constexpr double kGridCellMm = 3.0;

}  // namespace

std::int8_t TissueNear(const TriMesh& initial, const std::vector<std::int8_t>& labels,
                       const Vec3& p_mm) {
  if (labels.empty() || initial.tris.empty()) return kBoneTissue;
  double best = std::numeric_limits<double>::infinity();
  std::size_t best_i = 0;
  for (std::size_t i = 0; i < initial.tris.size(); ++i) {
    const double d2 = (Centroid(initial.nodes, initial.tris[i]) - p_mm).squaredNorm();
    if (d2 < best) {
      best = d2;
      best_i = i;
    }
  }
  return best_i < labels.size() ? labels[best_i] : kBoneTissue;
}

std::vector<std::int8_t> TriangleTissues(const TriMesh& initial,
                                         const std::vector<std::int8_t>& labels,
                                         const TriMesh& now) {
  std::vector<std::int8_t> out(now.tris.size(), kBoneTissue);
  if (labels.empty() || initial.tris.empty()) return out;
  const std::size_t kept = std::min({now.tris.size(), initial.tris.size(), labels.size()});
  std::copy(labels.begin(), labels.begin() + static_cast<std::ptrdiff_t>(kept), out.begin());
  if (now.tris.size() <= initial.tris.size()) return out;
  const CentroidGrid grid(initial, kGridCellMm);
  for (std::size_t i = initial.tris.size(); i < now.tris.size(); ++i) {
    const std::int32_t j = grid.Nearest(Centroid(now.nodes, now.tris[i]));
    if (static_cast<std::size_t>(j) < labels.size()) out[i] = labels[static_cast<std::size_t>(j)];
  }
  return out;
}

}  // namespace arthrosim::mesh
