#include "arthrosim/physics/thread_collision.h"

#include <algorithm>
#include <numeric>

namespace arthrosim::physics {

Box3 SweptSegmentBox(const Vec3& a0, const Vec3& a1, const Vec3& b0, const Vec3& b1, double pad) {
  Box3 box;
  box.min = a0.cwiseMin(a1).cwiseMin(b0).cwiseMin(b1).array() - pad;
  box.max = a0.cwiseMax(a1).cwiseMax(b0).cwiseMax(b1).array() + pad;
  return box;
}

std::vector<std::array<int, 2>> OverlappingPairs(const std::vector<Box3>& boxes) {
  std::vector<int> order;
  std::vector<std::array<int, 2>> pairs;
  OverlappingPairs(boxes, &order, &pairs);
  return pairs;
}

void OverlappingPairs(const std::vector<Box3>& boxes, std::vector<int>* order_out,
                      std::vector<std::array<int, 2>>* pairs) {
  const int n = static_cast<int>(boxes.size());
  std::vector<int>& order = *order_out;
  order.resize(n);
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](int a, int b) {
    if (boxes[a].min.x() != boxes[b].min.x()) return boxes[a].min.x() < boxes[b].min.x();
    return a < b;  // total tie-break
  });
  pairs->clear();
  for (int oi = 0; oi < n; ++oi) {
    const Box3& bi = boxes[order[oi]];
    for (int oj = oi + 1; oj < n; ++oj) {
      const Box3& bj = boxes[order[oj]];
      if (bj.min.x() > bi.max.x()) break;
      if (bj.min.y() > bi.max.y() || bi.min.y() > bj.max.y()) continue;
      if (bj.min.z() > bi.max.z() || bi.min.z() > bj.max.z()) continue;
      pairs->push_back({std::min(order[oi], order[oj]), std::max(order[oi], order[oj])});
    }
  }
  std::sort(pairs->begin(), pairs->end());
}

}  // namespace arthrosim::physics
