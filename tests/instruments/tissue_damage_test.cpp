// The burr on a bone's own tissue (scenarios/rotator_cuff_repair_anatomic.yaml: the humerus's
// articular cartilage): the removal is recorded as collateral damage, its burr event naming the
// tissue (`tissue=cartilage`), which plans protect (docs/plan-format.md); on the footprint, bone
// of the same humerus, it is not.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "arthrosim/instruments/instruments.h"
#include "arthrosim/io/scenario_loader.h"
#include "arthrosim/mesh/surface_tissue.h"

namespace arthrosim::instruments {
namespace {

const Model& Anatomic() {
  static const Model m = io::LoadScenario(std::string(ARTHROSIM_SOURCE_DIR) +
                                          "/scenarios/rotator_cuff_repair_anatomic.yaml");
  return m;
}

// Centroid and outward unit normal of the humerus triangle nearest to `p` with label `label`.
void NearestTriangle(const BoneModel& b, std::int8_t label, const Vec3& p, Vec3* at, Vec3* n) {
  double best = 1e300;
  for (std::size_t t = 0; t < b.surface.tris.size(); ++t) {
    if (b.tri_tissue[t] != label) continue;
    const mesh::Tri& tri = b.surface.tris[t];
    const Vec3 a = b.surface.nodes.col(tri[0]), c1 = b.surface.nodes.col(tri[1]),
               c2 = b.surface.nodes.col(tri[2]);
    const Vec3 c = (a + c1 + c2) / 3.0;
    if ((c - p).norm() >= best) continue;
    best = (c - p).norm();
    *at = c;
    *n = (c1 - a).cross(c2 - a).normalized();
  }
}

struct BurrPass {
  std::vector<Event> events;  // burr events
  double removed_mm3 = 0;     // humerus
};

// Half a second of burring with the head pressed 0.6 mm into the surface at `at` (normal n).
BurrPass Burr(const Model& m, const Vec3& at, const Vec3& n) {
  State s = MakeInitialState(m);
  const int burr = m.FindInstrument("burr");
  const double r = m.instruments[static_cast<std::size_t>(burr)].tip_radius_mm;
  ToolState& tool = s.tools[0];
  tool.instrument = burr;
  tool.buttons = 1;
  const Vec3 centre = at + n * (r - 0.6);
  tool.pose.position_mm = centre - n * r;  // the tip, one radius ahead of the head centre
  tool.pose.orientation = Quat::FromTwoVectors(Vec3::UnitZ(), -n);
  tool.handle_pose = tool.pose;  // no press: the tool acts where it is
  BurrPass out;
  for (int k = 0; k < 25; ++k) {
    s.step += 1;
    s.time_s = static_cast<double>(s.step) * m.options.dt_s;
    s.events.clear();
    InstrumentScratch scratch;
    ApplyInstruments(m, StepContext{}, &s, &scratch);
    for (const Event& e : s.events)
      if (e.kind == "burr") out.events.push_back(e);
  }
  out.removed_mm3 = s.bones[static_cast<std::size_t>(m.FindBone("humerus"))].removed_volume_mm3;
  return out;
}

TEST(TissueDamage, BurrOnTheCartilageIsRecordedAsCollateralDamageOnTheFootprintNot) {
  const Model& m = Anatomic();
  const BoneModel& hum = m.bones[static_cast<std::size_t>(m.FindBone("humerus"))];
  ASSERT_EQ(hum.tissues, std::vector<std::string>{"cartilage"});
  ASSERT_EQ(hum.tri_tissue.size(), hum.surface.tris.size());
  // cartilage on the superomedial head (under the cuff, away from the glenoid), bone at the
  // footprint centre
  const Vec3 joint = 22.5 * Vec3(-0.4, -0.2, 1.0).normalized();
  const Vec3 fp =
      m.landmarks[static_cast<std::size_t>(m.FindLandmark("footprint_center"))].position_mm;
  Vec3 cart_at, cart_n, bone_at, bone_n;
  NearestTriangle(hum, 0, joint, &cart_at, &cart_n);
  NearestTriangle(hum, mesh::kBoneTissue, fp, &bone_at, &bone_n);

  const BurrPass cart = Burr(m, cart_at, cart_n);
  const BurrPass bone = Burr(m, bone_at, bone_n);
  std::printf("cartilage: %zu burr events, %.4f mm3 removed; footprint: %zu events, %.4f mm3\n",
              cart.events.size(), cart.removed_mm3, bone.events.size(), bone.removed_mm3);
  ASSERT_FALSE(cart.events.empty());
  EXPECT_GT(cart.removed_mm3, 0.05);
  for (const Event& e : cart.events) {
    EXPECT_EQ(e.body, "humerus");
    EXPECT_NE(e.detail.find(" tissue=cartilage"), std::string::npos) << e.detail;
  }
  ASSERT_FALSE(bone.events.empty());
  EXPECT_GT(bone.removed_mm3, 0.05);
  for (const Event& e : bone.events)
    EXPECT_EQ(e.detail.find("tissue="), std::string::npos) << e.detail;
}

}  // namespace
}  // namespace arthrosim::instruments
