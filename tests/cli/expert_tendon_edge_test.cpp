// The torn edge's distance to the footprint in the expert repair, from its run file
// (expert_run.h): the gap the knot pusher reports, and the plan's measure of the reduction.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <set>
#include <string>
#include <vector>

#include "arthrosim/core/soft_nodes.h"
#include "expert_run.h"

namespace arthrosim {
namespace {

using namespace expert;  // NOLINT(google-build-using-namespace): the run and its helpers

// The residual gap of the repair as the knot pusher reports it (docs/operations.md): the
// smallest distance from a node of region tendon_edge to the box of region footprint, mm.
double EdgeGapMm(const State& s) {
  const Region& edge = RegionNamed("tendon_edge");
  const Region& foot = RegionNamed("footprint");
  const SoftBodyState& tendon = s.soft_bodies[SoftIndex(edge.body)];
  const std::vector<std::uint8_t> in_tissue = NodesInAliveTets(tendon);  // not cut-off debris
  double best = std::numeric_limits<double>::infinity();
  for (const std::int32_t n : edge.nodes) {
    if (!in_tissue[static_cast<std::size_t>(n)]) continue;
    const Vec3 p = tendon.x.col(n);
    best = std::min(best, (p - p.cwiseMax(foot.box_min_mm).cwiseMin(foot.box_max_mm)).norm());
  }
  return best;
}

// The repair's residual gap (docs/operations.md, knot_seated gap_mm): the smallest distance from
// the torn edge (region tendon_edge) to the footprint box, measured from the run file before
// the passes, at the knot's seating and at the end; the knot_seated event reports the seating
// frame's figure. Nodes the debridement left without elements (frozen where they were cut) are
// not the edge: they are skipped (NodesInAliveTets), as the knot pusher and scoring skip them.
TEST(ExpertRepair, TendonEdgeGapMeasured) {
  const Event anchor = FirstEvent("anchor");
  const Event seated = FirstEvent("knot_seated");
  ASSERT_EQ(anchor.kind, "anchor");
  ASSERT_EQ(seated.kind, "knot_seated");
  const double before = EdgeGapMm(FrameAt(anchor.time_s));
  const double at_seat = EdgeGapMm(FrameAt(seated.time_s));
  const double end = EdgeGapMm(Last());
  std::printf(
      "tendon edge to footprint: %.3f mm at the anchor (%.2f s), %.3f mm at the knot's "
      "seating (%.2f s; event %s), %.3f mm at the end\n",
      before, anchor.time_s, at_seat, seated.time_s, DetailText(seated, "gap_mm").c_str(), end);
  EXPECT_NEAR(DetailValue(seated, "gap_mm"), at_seat, 0.001);
}

// The plan's measure of the reduction (scenarios/plans/rotator_cuff_repair.yaml, step
// tendon_reduced): the centroid of region tendon_edge to the nearest point of region
// footprint's box (0 over the bone bed), mm.
double EdgeCentroidToFootprintMm(const State& s) {
  const Region& edge = RegionNamed("tendon_edge");
  const Region& foot = RegionNamed("footprint");
  const SoftBodyState& tendon = s.soft_bodies[SoftIndex(edge.body)];
  const std::vector<std::uint8_t> in_tissue = NodesInAliveTets(tendon);
  Vec3 c = Vec3::Zero();
  int count = 0;
  for (const std::int32_t n : edge.nodes) {
    if (!in_tissue[static_cast<std::size_t>(n)]) continue;
    c += tendon.x.col(n);
    ++count;
  }
  c /= static_cast<double>(count);
  return (c - c.cwiseMax(foot.box_min_mm).cwiseMin(foot.box_max_mm)).norm();
}

// Issue #16's target: the repair holds the edge within 2 mm of the footprint, measured as the
// plan measures it (10.1 mm at t = 0). The grasper draws the edge onto the footprint before the
// passes, holds it while the knot is tied and lets go seconds before the end, so at the end the
// limbs (taut from the anchor to their bites) and the knot hold it, not the grasper.
// Fails on the expert run before the reduction (27.4 mm at the end: limbs loaded 24 mm below
// the anchor, slack between anchor and bite, the edge sprang back when the grasper let go).
TEST(ExpertRepair, TendonEdgeOnTheFootprint) {
  const double start_mm = EdgeCentroidToFootprintMm(TheRun().first);
  const double end_mm = EdgeCentroidToFootprintMm(Last());
  std::printf("tendon edge centroid to the footprint bed: %.3f mm at t = 0, %.3f mm at the end\n",
              start_mm, end_mm);
  EXPECT_GT(start_mm, 8.0) << "the scene's retracted tear";
  EXPECT_LE(end_mm, 2.0);
  double last_release_s = -1;
  for (const Event& e : Events())
    if (e.kind == "release" && e.tool == "grasper") last_release_s = e.time_s;
  ASSERT_GE(last_release_s, 0) << "the grasper never let go";
  EXPECT_LT(last_release_s, TheRun().time_s.back() - 5.0) << "the grasper held it until the end";
}

}  // namespace
}  // namespace arthrosim
