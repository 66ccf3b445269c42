#include "arthrosim/collision/instrument_shape.h"

#include <gtest/gtest.h>

#include <cmath>

#include "arthrosim/core/units.h"

namespace arthrosim::collision {
namespace {

InstrumentModel Make(InstrumentKind kind) {
  InstrumentModel m;
  m.name = InstrumentKindName(kind);
  m.kind = kind;
  return m;
}

TEST(InstrumentShape, EveryKindHasAShaftOfTheModelDiameterBehindTheTip) {
  for (int k = 0; k < kInstrumentKindCount; ++k) {
    InstrumentModel m = Make(static_cast<InstrumentKind>(k));
    m.shaft_diameter_mm = 5.5;
    const auto prims = InstrumentPrimitivesLocal(m, 0.3);
    ASSERT_GE(prims.size(), 2u) << m.name;
    const ToolPrimitive& shaft = prims.back();
    EXPECT_EQ(shaft.part, ToolPart::kShaft);
    EXPECT_EQ(shaft.radius_mm, 2.75);
    EXPECT_EQ(shaft.core.v[1].z(), -m.shaft_length_mm);
    // Tip at the origin, shaft along -z: no core point ahead of the tip.
    for (const ToolPrimitive& p : prims) {
      for (int i = 0; i < p.core.n; ++i) EXPECT_LE(p.core.v[i].z(), 1e-12) << m.name;
    }
    // The primitive list does not depend on the jaw value.
    const auto closed = InstrumentPrimitivesLocal(m, 1.0);
    ASSERT_EQ(closed.size(), prims.size());
    for (std::size_t i = 0; i < prims.size(); ++i) {
      EXPECT_EQ(closed[i].part, prims[i].part);
      EXPECT_EQ(closed[i].core.n, prims[i].core.n);
    }
  }
}

TEST(InstrumentShape, JawsOpenByTheModelAngle) {
  for (InstrumentKind kind :
       {InstrumentKind::kScissors, InstrumentKind::kGrasper, InstrumentKind::kScorpionNeedle}) {
    const InstrumentModel m = Make(kind);
    const auto open = InstrumentPrimitivesLocal(m, 0.0);
    // Blade cutting edge / jaw axis runs hinge -> tip; the angle between the two tips seen from
    // the hinge is the opening.
    const Vec3 hinge(0, 0, -m.tip_length_mm);
    auto tip = [&](const ToolPrimitive& p) {
      return p.part == ToolPart::kBlade ? p.core.v[1] : p.core.v[2];
    };
    const auto closed = InstrumentPrimitivesLocal(m, 1.0);
    for (int side = 0; side < 2; ++side) {
      const Vec3 a = (tip(open[side]) - hinge).normalized();
      const Vec3 b = (tip(closed[side]) - hinge).normalized();
      EXPECT_NEAR(std::acos(a.dot(b)) / units::kDegToRad, 0.5 * MaxOpeningDeg(kind), 1e-6)
          << m.name;
    }
    EXPECT_GT(tip(open[0]).x(), tip(closed[0]).x());  // side 0 opens towards +x
    EXPECT_NEAR(tip(closed[0]).x() - tip(closed[1]).x(),
                kind == InstrumentKind::kScissors ? 0 : 1.0, 1e-12);
  }
}

TEST(InstrumentShape, BurrSphereTouchesTheTipAndWorldTransformApplies) {
  Model model;
  InstrumentModel burr = Make(InstrumentKind::kBurr);
  burr.tip_radius_mm = 2.5;
  model.instruments.push_back(burr);
  ToolState tool;
  EXPECT_TRUE(ToolPrimitivesWorld(model, tool).empty());  // nothing inserted
  tool.instrument = 0;
  tool.pose.position_mm = Vec3(10, 20, 30);
  tool.pose.orientation = Quat(Eigen::AngleAxisd(units::kPi, Vec3::UnitX()));  // pointing down
  const auto prims = ToolPrimitivesWorld(model, tool);
  ASSERT_EQ(prims[0].part, ToolPart::kBurr);
  EXPECT_LT((prims[0].core.v[0] - Vec3(10, 20, 32.5)).norm(), 1e-12);
  EXPECT_EQ(prims[0].radius_mm, 2.5);
}

}  // namespace
}  // namespace arthrosim::collision
