#pragma once
// The tool proxy tests' own measure of an instrument's clearance from bone, independent of the
// proxy's search (tool_proxy_test.cpp, tool_proxy_jam_test.cpp).
#include <algorithm>

#include "arthrosim/collision/instrument_shape.h"
#include "arthrosim/collision/tool_bone_query.h"
#include "arthrosim/core/model.h"
#include "arthrosim/core/state.h"

namespace arthrosim::sim::testing {

/// Smallest clearance (signed distance - radius, mm; < 0 inside bone) of the contacting parts of
/// the instrument in `slot` from the bones of `s`, from points sampled every 0.2 mm over each
/// part's core with the exact point query (a different search from the proxy's own). A sample
/// more than kFarMm outside the box around every bone node counts its distance to that box (a
/// lower bound of its clearance, and the exact query there would visit every triangle): figures
/// below kFarMm - radius are exact.
inline double SampledClearance(const Model& m, const State& s, int slot) {
  constexpr double kFarMm = 3.0;
  collision::BoneQueryWorld bones;
  collision::SyncBoneQuery(s, &bones);
  Vec3 lo = Vec3::Constant(1e300), hi = Vec3::Constant(-1e300);
  for (const BoneState& b : s.bones) {
    if (b.surface.nodes.cols() == 0) continue;
    lo = lo.cwiseMin(b.surface.nodes.rowwise().minCoeff());
    hi = hi.cwiseMax(b.surface.nodes.rowwise().maxCoeff());
  }
  double lowest = 1e300;
  for (const collision::ToolPrimitive& p :
       collision::ToolPrimitivesWorld(m, s.tools[static_cast<std::size_t>(slot)])) {
    if (!p.contacts) continue;
    auto sample = [&](const Vec3& a, const Vec3& b) {
      const int n = 1 + static_cast<int>((b - a).norm() / 0.2);
      for (int i = 0; i <= n; ++i) {
        const Vec3 x = a + (b - a) * (static_cast<double>(i) / n);
        const double to_box = (x - x.cwiseMax(lo).cwiseMin(hi)).norm();
        const double distance =
            to_box > kFarMm ? to_box : collision::PointBoneSignedDistance(x, &bones);
        lowest = std::min(lowest, distance - p.radius_mm);
      }
    };
    const auto& v = p.core.v;
    if (p.core.n == 1) sample(v[0], v[0]);
    for (int i = 0; i < p.core.n && p.core.n > 1; ++i) sample(v[i], v[(i + 1) % p.core.n]);
  }
  return lowest;
}

}  // namespace arthrosim::sim::testing
