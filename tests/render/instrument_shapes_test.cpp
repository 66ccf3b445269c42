// What the trainee sees is what touches: the drawn instrument is the collision primitives.
#include "instrument_shapes.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <limits>

#include "arthrosim/collision/instrument_shape.h"

namespace arthrosim::render {
namespace {

constexpr double kTolMm = 0.01;

// Axis-aligned box of the rounded primitives (core points +- radius), tool frame.
Eigen::AlignedBox3d PrimitiveBox(const std::vector<collision::ToolPrimitive>& prims) {
  Eigen::AlignedBox3d box;
  for (const collision::ToolPrimitive& p : prims) {
    for (int i = 0; i < p.core.n; ++i) {
      box.extend(p.core.v[i] + Vec3::Constant(p.radius_mm));
      box.extend(p.core.v[i] - Vec3::Constant(p.radius_mm));
    }
  }
  return box;
}

// Distance from q to the nearest rounded primitive's surface or inside (<= 0 inside), mm.
double GapToPrimitives(const Vec3& q, const std::vector<collision::ToolPrimitive>& prims) {
  double best = std::numeric_limits<double>::infinity();
  for (const collision::ToolPrimitive& p : prims) {
    const double d =
        std::sqrt(collision::Closest(collision::PointSimplex(q), p.core).dist2) - p.radius_mm;
    best = std::min(best, d);
  }
  return best;
}

TEST(InstrumentShapes, DrawnShapeIsTheCollisionPrimitivesForEveryKind) {
  for (int k = 0; k < kInstrumentKindCount; ++k) {
    for (const double jaw : {0.0, 0.5, 1.0}) {
      InstrumentModel m;
      m.kind = static_cast<InstrumentKind>(k);
      m.name = InstrumentKindName(m.kind);
      m.shaft_diameter_mm = 5.5;
      m.tip_length_mm = 7;
      m.tip_radius_mm = 2.75;
      SceneMesh metal, dark;
      AppendInstrument(m, jaw, Pose{}, &metal, &dark);
      const auto prims = collision::InstrumentPrimitivesLocal(m, jaw);
      Eigen::AlignedBox3d drawn;
      double worst_gap = -std::numeric_limits<double>::infinity();
      for (const SceneMesh* mesh : {&metal, &dark}) {
        for (const Vertex& v : mesh->vertices) {
          const Vec3 q(v.pos[0], v.pos[1], v.pos[2]);
          drawn.extend(q);
          worst_gap = std::max(worst_gap, GapToPrimitives(q, prims));
        }
      }
      const Eigen::AlignedBox3d want = PrimitiveBox(prims);
      ASSERT_FALSE(drawn.isEmpty()) << m.name;
      for (int a = 0; a < 3; ++a) {
        EXPECT_NEAR(drawn.min()[a], want.min()[a], kTolMm)
            << m.name << " jaw " << jaw << " axis " << a;
        EXPECT_NEAR(drawn.max()[a], want.max()[a], kTolMm)
            << m.name << " jaw " << jaw << " axis " << a;
      }
      // Nothing drawn lies outside what collides.
      EXPECT_LE(worst_gap, kTolMm) << m.name << " jaw " << jaw;
    }
  }
}

TEST(InstrumentShapes, BurrHeadTouchesTheTipPointNotBeyondIt) {
  InstrumentModel m;
  m.kind = InstrumentKind::kBurr;
  m.tip_radius_mm = 2.75;
  SceneMesh metal, dark;
  AppendInstrument(m, 0, Pose{}, &metal, &dark);
  double front = -1e300;
  for (const Vertex& v : metal.vertices) front = std::max(front, static_cast<double>(v.pos[2]));
  EXPECT_NEAR(front, 0.0, kTolMm);
}

}  // namespace
}  // namespace arthrosim::render
