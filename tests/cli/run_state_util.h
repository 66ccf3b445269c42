#pragma once
// Helpers shared by the tests that judge a run from its file: where a constraint end is, and
// which connected piece each node of a soft body belongs to.
#include <cstddef>
#include <cstdint>
#include <numeric>
#include <vector>

#include "arthrosim/core/state.h"

namespace arthrosim::testing {

/// World position (mm) of a constraint end in a frame read back from a run file.
inline Vec3 EndAt(const State& s, const ConstraintEnd& e) {
  const auto weighted = [&](const Points& x) {
    Vec3 p = Vec3::Zero();
    for (std::size_t k = 0; k < 4; ++k)
      if (e.nodes[k] >= 0 && e.weights[k] != 0) p += e.weights[k] * x.col(e.nodes[k]);
    return p;
  };
  switch (e.kind) {
    case ConstraintEnd::Kind::kTool:
      return s.tools[static_cast<std::size_t>(e.index)].pose.Apply(e.offset_mm);
    case ConstraintEnd::Kind::kSoftBody:
      return weighted(s.soft_bodies[static_cast<std::size_t>(e.index)].x);
    case ConstraintEnd::Kind::kThread:
      return weighted(s.threads[static_cast<std::size_t>(e.index)].x);
    default:
      return e.offset_mm;
  }
}

/// Union-find root of node i.
inline int Root(std::vector<int>* parent, int i) {
  while ((*parent)[static_cast<std::size_t>(i)] != i) i = (*parent)[static_cast<std::size_t>(i)];
  return i;
}

/// Component label (root node) of every node of the alive tets, -1 for nodes no alive tet uses;
/// sharing a node connects.
inline std::vector<int> ComponentOf(const SoftBodyState& b) {
  std::vector<int> parent(static_cast<std::size_t>(b.x.cols()));
  std::iota(parent.begin(), parent.end(), 0);
  std::vector<std::uint8_t> used(parent.size(), 0);
  for (std::size_t t = 0; t < b.tets.size(); ++t) {
    if (!b.tet_alive[t]) continue;
    for (std::int32_t n : b.tets[t]) {
      used[static_cast<std::size_t>(n)] = 1;
      parent[static_cast<std::size_t>(Root(&parent, n))] = Root(&parent, b.tets[t][0]);
    }
  }
  std::vector<int> label(parent.size(), -1);
  for (std::size_t i = 0; i < parent.size(); ++i) {
    if (used[i]) label[i] = Root(&parent, static_cast<int>(i));
  }
  return label;
}

}  // namespace arthrosim::testing
