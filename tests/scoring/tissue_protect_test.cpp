// A plan protects a bone's own tissue (`protected: [{body: humerus, tissue: cartilage}]`,
// docs/plan-format.md) on the anatomic scene: burr events naming the tissue (`tissue=cartilage`,
// written by the burr) and contacts nearest to its triangles count for it; those on the rest of
// the bone (the footprint) do not; a tissue the bone does not have is an error naming the field.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "arthrosim/core/error.h"
#include "arthrosim/io/scenario_loader.h"
#include "arthrosim/mesh/surface_tissue.h"
#include "arthrosim/scoring/plan.h"
#include "progress.h"

namespace arthrosim::scoring {
namespace {

const Model& Anatomic() {
  static const Model m = io::LoadScenario(std::string(ARTHROSIM_SOURCE_DIR) +
                                          "/scenarios/rotator_cuff_repair_anatomic.yaml");
  return m;
}

std::string PlanText(const std::string& tissue) {
  return "name: protect\n"
         "scenario: rotator_cuff_repair_anatomic\n"
         "protected:\n"
         "  - {name: cartilage, body: humerus, tissue: " +
         tissue +
         ", max_force: 2.0}\n"
         "steps:\n"
         "  - id: look\n"
         "    title: Look\n"
         "    instruments: [camera]\n"
         "    complete:\n"
         "      - in_view: {landmark: footprint_center, min_time: 0.2}\n"
         "    time_budget: 5\n";
}

// Centroid of a humerus triangle with `label`, nearest to p.
Vec3 OnLabel(const BoneModel& b, std::int8_t label, const Vec3& p) {
  double best = 1e300;
  Vec3 at = Vec3::Zero();
  for (std::size_t t = 0; t < b.surface.tris.size(); ++t) {
    if (b.tri_tissue[t] != label) continue;
    const mesh::Tri& tri = b.surface.tris[t];
    const Vec3 c =
        (b.surface.nodes.col(tri[0]) + b.surface.nodes.col(tri[1]) + b.surface.nodes.col(tri[2])) /
        3.0;
    if ((c - p).norm() < best) {
      best = (c - p).norm();
      at = c;
    }
  }
  return at;
}

TEST(TissueProtect, OnlyDamageAndContactOnTheTissueCount) {
  const Model& m = Anatomic();
  const Plan plan = LoadPlanFromText(PlanText("cartilage"), "protect.yaml", &m);
  ASSERT_EQ(plan.protected_structures.size(), 1u);
  const ProtectedStructure& p = plan.protected_structures[0];
  EXPECT_EQ(p.tissue, "cartilage");

  Event on{1, 0.02, "burr", "burr", "humerus", "volume_mm3=0.1 tissue=cartilage", Vec3::Zero()};
  Event off = on;
  off.detail = "volume_mm3=0.1";
  EXPECT_TRUE(detail::DamagesProtected(m, p, on));
  EXPECT_FALSE(detail::DamagesProtected(m, p, off));

  const int h = m.FindBone("humerus");
  const BoneModel& hum = m.bones[static_cast<std::size_t>(h)];
  const Vec3 cart = OnLabel(hum, 0, 22.5 * Vec3(-0.4, -0.2, 1.0).normalized());
  const Vec3 fp = OnLabel(
      hum, mesh::kBoneTissue,
      m.landmarks[static_cast<std::size_t>(m.FindLandmark("footprint_center"))].position_mm);
  const detail::SlotForces force{1.0, 0.0};
  const ToolContact c_cart{0, ConstraintEnd::Kind::kBone, h, cart};
  const ToolContact c_fp{0, ConstraintEnd::Kind::kBone, h, fp};
  EXPECT_TRUE(detail::TouchOf(m, p, {c_cart}, force).touching);
  EXPECT_FALSE(detail::TouchOf(m, p, {c_fp}, force).touching);

  // without the tissue key the structure is the whole humerus: both count
  ProtectedStructure whole = p;
  whole.tissue.clear();
  EXPECT_TRUE(detail::DamagesProtected(m, whole, off));
  EXPECT_TRUE(detail::TouchOf(m, whole, {c_fp}, force).touching);
}

TEST(TissueProtect, UnknownTissueIsAnErrorNamingTheField) {
  try {
    LoadPlanFromText(PlanText("meniscus"), "protect.yaml", &Anatomic());
    FAIL() << "accepted a tissue the humerus does not have";
  } catch (const InputError& e) {
    EXPECT_EQ(e.field(), "protected[0].tissue") << e.what();
    EXPECT_NE(std::string(e.what()).find("meniscus"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace arthrosim::scoring
