#include "arthrosim/core/instrument_geometry.h"

#include <algorithm>
#include <cmath>

#include "arthrosim/core/units.h"

namespace arthrosim {
namespace {

// Thin parts: half-thicknesses (mm). A real scissor blade is ~0.5 mm thick, a grasper jaw ~1 mm.
constexpr double kBladeHalfThickness = 0.25;
constexpr double kJawHalfThickness = 0.5;
constexpr double kNeedleRadius = 0.3;
constexpr double kAwlPointRadius = 0.5;
constexpr double kHookLength = 3.0;  // crochet-hook barb length, mm
constexpr double kMaxHookRadius = 0.75;

void Add(InstrumentParts* out, const InstrumentPart& p) {
  out->parts[static_cast<std::size_t>(out->count++)] = p;
}

InstrumentPart Sphere(ToolPart part, const Vec3& c, double r) {
  return InstrumentPart{part, 0, 1, {c, Vec3::Zero(), Vec3::Zero()}, r, true};
}

InstrumentPart Capsule(ToolPart part, const Vec3& a, const Vec3& b, double r, int side = 0) {
  return InstrumentPart{part, side, 2, {a, b, Vec3::Zero()}, r, true};
}

InstrumentPart Triangle(ToolPart part, const Vec3& a, const Vec3& b, const Vec3& c, double r,
                        int side, bool contacts) {
  return InstrumentPart{part, side, 3, {a, b, c}, r, contacts};
}

// Rotation about the y axis through the hinge point by angle a (rad): positive moves +z to +x.
Vec3 AboutHinge(const Vec3& p, const Vec3& hinge, double a) {
  const Vec3 d = p - hinge;
  return hinge + Vec3(d.x() * std::cos(a) + d.z() * std::sin(a), d.y(),
                      -d.x() * std::sin(a) + d.z() * std::cos(a));
}

// Two blades (plates in the x-z plane, cutting edge hinge->tip) or two jaws (paddles across y
// that close face to face), hinged at z = -L and opened symmetrically by theta.
void AddPair(InstrumentParts* out, ToolPart part, double length, double width, double theta) {
  const Vec3 hinge(0, 0, -length);
  for (int side = 0; side < 2; ++side) {
    const double s = side == 0 ? 1.0 : -1.0;
    const double a = s * 0.5 * theta;
    std::array<Vec3, 3> v;
    if (part == ToolPart::kBlade) {
      v = {hinge, Vec3::Zero(), Vec3(s * width, 0, -length)};
    } else {
      const double off = s * kJawHalfThickness;  // closed jaws touch face to face
      v = {Vec3(off, -0.5 * width, -length), Vec3(off, 0.5 * width, -length), Vec3(off, 0, 0)};
    }
    for (Vec3& p : v) p = AboutHinge(p, hinge, a);
    const double r = part == ToolPart::kBlade ? kBladeHalfThickness : kJawHalfThickness;
    Add(out, Triangle(part, v[0], v[1], v[2], r, side, true));
  }
}

}  // namespace

double MaxOpeningDeg(InstrumentKind kind) {
  switch (kind) {
    case InstrumentKind::kScissors:
      return 40;
    case InstrumentKind::kCutter:
      return 30;
    case InstrumentKind::kGrasper:
      return 50;
    case InstrumentKind::kRetriever:
      return 40;
    case InstrumentKind::kScorpionNeedle:
      return 60;
    default:
      return 0;
  }
}

InstrumentParts InstrumentPartsLocal(const InstrumentModel& m, double jaw) {
  InstrumentParts out;
  const double shaft_r = 0.5 * m.shaft_diameter_mm;
  const double length = std::max(m.tip_length_mm, 1e-3);
  const double theta = (1.0 - std::clamp(jaw, 0.0, 1.0)) * MaxOpeningDeg(m.kind) * units::kDegToRad;
  const double tip_r = std::min(m.tip_radius_mm, shaft_r);
  switch (m.kind) {
    case InstrumentKind::kScissors:
    case InstrumentKind::kCutter:
      AddPair(&out, ToolPart::kBlade, length, 0.4 * m.shaft_diameter_mm, theta);
      break;
    case InstrumentKind::kGrasper:
    case InstrumentKind::kRetriever:
      AddPair(&out, ToolPart::kJaw, length, 0.6 * m.shaft_diameter_mm, theta);
      break;
    case InstrumentKind::kScorpionNeedle: {
      AddPair(&out, ToolPart::kJaw, length, 0.6 * m.shaft_diameter_mm, theta);
      InstrumentPart needle =
          Capsule(ToolPart::kNeedle, Vec3(0, 0, -length), Vec3(0, 0, -0.1 * length), kNeedleRadius);
      needle.contacts = false;
      Add(&out, needle);
      break;
    }
    case InstrumentKind::kBurr: {
      // Burr head: a sphere whose front touches the tip point.
      const double r = m.tip_radius_mm;
      Add(&out, Sphere(ToolPart::kBurr, Vec3(0, 0, -r), r));
      // Shank between the burr head and the sheath.
      Add(&out, Capsule(ToolPart::kShaft, Vec3(0, 0, -r), Vec3(0, 0, -std::max(length, 2 * r)),
                        std::min(1.0, r), 1));
      break;
    }
    case InstrumentKind::kShaver: {
      Add(&out, Capsule(ToolPart::kShaverTip, Vec3(0, 0, -shaft_r),
                        Vec3(0, 0, -std::max(length, shaft_r)), shaft_r));
      const double hw = tip_r;
      const double z0 = -shaft_r - 0.5, z1 = std::min(z0 - 1.0, -length);
      const Vec3 a(shaft_r, -hw, z0), b(shaft_r, hw, z0), c(shaft_r, hw, z1), d(shaft_r, -hw, z1);
      Add(&out, Triangle(ToolPart::kShaverWindow, a, b, c, 0, 0, false));
      Add(&out, Triangle(ToolPart::kShaverWindow, a, c, d, 0, 1, false));
      break;
    }
    case InstrumentKind::kElectrocautery:
      Add(&out, Capsule(ToolPart::kCauteryTip, Vec3(0, 0, -tip_r),
                        Vec3(0, 0, -std::max(length, tip_r)), tip_r));
      break;
    case InstrumentKind::kAwl: {
      const double zb = -std::max(0.4 * length, kAwlPointRadius);
      Add(&out, Capsule(ToolPart::kAwlTip, Vec3(0, 0, -kAwlPointRadius), Vec3(0, 0, zb),
                        kAwlPointRadius));
      Add(&out, Capsule(ToolPart::kAwlBody, Vec3(0, 0, zb), Vec3(0, 0, -length), tip_r));
      break;
    }
    case InstrumentKind::kHook: {
      const double r = std::min(tip_r, kMaxHookRadius);
      Add(&out, Capsule(ToolPart::kHook, Vec3(0, 0, -length), Vec3::Zero(), r, 1));
      Add(&out, Capsule(ToolPart::kHook, Vec3::Zero(),
                        Vec3(0.7 * kHookLength, 0, -0.7 * kHookLength), r, 0));
      break;
    }
    case InstrumentKind::kKnotPusher:
      Add(&out, Capsule(ToolPart::kPusherTip, Vec3(0, 0, -tip_r),
                        Vec3(0, 0, -std::max(length, tip_r)), tip_r));
      break;
  }
  // The shaft runs from the end of the working part back to the handle.
  Add(&out, Capsule(ToolPart::kShaft, Vec3(0, 0, -length),
                    Vec3(0, 0, -std::max(m.shaft_length_mm, length)), shaft_r));
  return out;
}

}  // namespace arthrosim
