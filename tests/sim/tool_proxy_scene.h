#pragma once
// The tool proxy tests' shared pieces (tool_proxy_test.cpp, tool_proxy_jam_test.cpp): their scene
// (a 5.5 mm burr over a bone, stepped by sim::Step) and their own measure of an instrument's
// clearance from bone, independent of the proxy's search.
#include <algorithm>
#include <string>
#include <utility>

#include "arthrosim/collision/instrument_shape.h"
#include "arthrosim/collision/tool_bone_query.h"
#include "arthrosim/core/model.h"
#include "arthrosim/core/state.h"
#include "arthrosim/sim/step.h"

namespace arthrosim::sim::testing {

/// A model named `name` with `bone`, a portal "top" at (0, 0, 60) and a 5.5 mm burr (tip length
/// 5.5, radius 2.75) in it; no gravity. The proxy options are the defaults (sliding).
inline Model BurrOverBone(std::string name, BoneModel bone) {
  Model m;
  m.name = std::move(name);
  m.bones.push_back(std::move(bone));
  m.portals.push_back({"top", Vec3(0, 0, 60)});
  InstrumentModel burr;
  burr.name = "burr";
  burr.kind = InstrumentKind::kBurr;
  burr.portal = "top";
  burr.shaft_diameter_mm = 5.5;
  burr.tip_length_mm = 5.5;
  burr.tip_radius_mm = 2.75;
  m.instruments.push_back(burr);
  m.options.gravity_mm_s2 = Vec3::Zero();
  return m;
}

/// A model, its state and workspace, stepped by sim::Step.
struct Sim {
  Model model;
  State state;
  Workspace ws;
  explicit Sim(Model m) : model(std::move(m)), state(MakeInitialState(model)) {
    BuildWorkspace(model, state, &ws);
  }
  void Step(const InputFrame& f) { sim::Step(model, f, &state, &ws); }
};

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
