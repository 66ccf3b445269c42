#include "instrument_shapes.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "mesh_builder.h"

namespace arthrosim::render {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr int kSides = 20;                           // facets around a shaft
constexpr double kMaxJawHalfAngle = 25 * kPi / 180;  // fully open jaw, each side

Eigen::Isometry3d ToIsometry(const Pose& pose) {
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.linear() = pose.orientation.normalized().toRotationMatrix();
  t.translation() = pose.position_mm;
  return t;
}

// Frame of a jaw hinged at z = -hinge, opened by `angle` about +y (positive: toward +x).
Eigen::Isometry3d JawFrame(double hinge, double angle, double x_offset) {
  return Eigen::Isometry3d(Eigen::Translation3d(0, 0, -hinge)) *
         Eigen::AngleAxisd(angle, Vec3::UnitY()) * Eigen::Translation3d(x_offset, 0, 0);
}

// Two jaws or blades: x extent `w` each, y extent `h`, tapering to `tip_scale`. When `one_moves`
// only the +x jaw opens (scorpion: the lower jaw is fixed), by twice the angle.
void Jaws(MeshBuilder* b, double tl, double w, double h, double tip_scale, double open,
          bool one_moves) {
  const double a = open * kMaxJawHalfAngle;
  const double upper = one_moves ? 2 * a : a, lower = one_moves ? 0.0 : -a;
  b->Blade(JawFrame(tl, upper, 0.5 * w), tl, w, h, tip_scale);
  b->Blade(JawFrame(tl, lower, -0.5 * w), tl, w, h, tip_scale);
}

}  // namespace

void AppendInstrument(const InstrumentModel& m, double jaw, const Pose& pose, SceneMesh* metal,
                      SceneMesh* dark) {
  const Eigen::Isometry3d frame = ToIsometry(pose);
  MeshBuilder b(metal, frame), d(dark, frame);
  const double r = 0.5 * m.shaft_diameter_mm, len = m.shaft_length_mm, tl = m.tip_length_mm,
               tr = m.tip_radius_mm;
  const double open = 1.0 - std::clamp(jaw, 0.0, 1.0);
  auto shaft = [&](MeshBuilder* mb, double z_end) {
    mb->Cylinder(Vec3(0, 0, -len), Vec3(0, 0, z_end), r, r, kSides, true, true);
  };
  switch (m.kind) {
    case InstrumentKind::kScissors:
      shaft(&b, -tl);
      Jaws(&b, tl, 0.35 * r, 1.2 * r, 0.25, open, false);
      break;
    case InstrumentKind::kCutter:
      shaft(&b, -tl);
      Jaws(&b, tl, 0.45 * r, 1.4 * r, 0.6, open, false);
      break;
    case InstrumentKind::kGrasper:
      shaft(&b, -tl);
      Jaws(&b, tl, 0.8 * r, 1.6 * r, 0.8, open, false);
      break;
    case InstrumentKind::kRetriever:
      shaft(&b, -tl);
      Jaws(&b, tl, 0.6 * r, 1.2 * r, 0.5, open, false);
      break;
    case InstrumentKind::kScorpionNeedle:
      shaft(&b, -tl);
      Jaws(&b, tl, 0.8 * r, 1.6 * r, 0.7, open, true);
      break;
    case InstrumentKind::kBurr:
      // sheath, then a thin neck to the burr sphere centred at the tip
      shaft(&b, -tl);
      b.Cylinder(Vec3(0, 0, -tl), Vec3(0, 0, 0), 0.35 * r, 0.35 * r, 12, false, false);
      b.Sphere(Vec3::Zero(), Vec3::Constant(tr), 12, 18);
      break;
    case InstrumentKind::kShaver: {
      // outer tube closed at the tip with a side window (+x) over the working length; the
      // dark inner blade shows through it
      const double gap = std::asin(std::min(1.0, tr / r));
      b.CylinderWithWindow(-len, 0.0, r, 24, 30, 0.0, gap, -tl, -0.5);
      b.Cylinder(Vec3(0, 0, -1e-3), Vec3::Zero(), r, r, 24, false, true);
      d.Cylinder(Vec3(0, 0, -tl - 1.0), Vec3(0, 0, -0.3), 0.75 * r, 0.75 * r, 16, true, true);
      break;
    }
    case InstrumentKind::kElectrocautery:
      // insulated shaft, bare electrode rod ending in a hook bent toward +x
      shaft(&d, -tl);
      b.Cylinder(Vec3(0, 0, -tl), Vec3(0, 0, 0), 0.4, 0.4, 10, false, false);
      b.Cylinder(Vec3(0, 0, 0), Vec3(1.8, 0, -0.6), 0.4, 0.35, 10, true, true);
      break;
    case InstrumentKind::kAwl:
      shaft(&b, -tl);
      b.Cylinder(Vec3(0, 0, -tl), Vec3(0, 0, 0), tr, 0.0, kSides, true, false);
      break;
    case InstrumentKind::kHook:
      // probe: thin rod, right-angle tip with a ball end
      shaft(&b, -tl);
      b.Cylinder(Vec3(0, 0, -tl), Vec3(0, 0, 0), 0.6, 0.6, 12, false, false);
      b.Cylinder(Vec3(0, 0, 0), Vec3(2.5, 0, 0), 0.6, 0.6, 12, false, false);
      b.Sphere(Vec3(0, 0, 0), Vec3::Constant(0.6), 8, 12);
      b.Sphere(Vec3(2.5, 0, 0), Vec3::Constant(0.8), 8, 12);
      break;
    case InstrumentKind::kKnotPusher:
      // eye at the tip: a ring in the y-z plane the suture passes through
      shaft(&b, -tr - 0.5);
      b.Torus(Vec3::Zero(), Vec3::UnitX(), std::max(tr, 0.8), 0.5, 24, 10);
      break;
  }
}

void AppendScope(const Pose& pose, double diameter_mm, SceneMesh* mesh) {
  MeshBuilder b(mesh, ToIsometry(pose));
  b.Cylinder(Vec3(0, 0, -150.0), Vec3::Zero(), 0.5 * diameter_mm, 0.5 * diameter_mm, kSides, true,
             true);
}

}  // namespace arthrosim::render
