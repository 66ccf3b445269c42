#include "instrument_shapes.h"

#include "arthrosim/core/instrument_geometry.h"
#include "mesh_builder.h"

namespace arthrosim::render {
namespace {

constexpr int kSides = 24;   // facets around a shaft, multiple of 4: spheres reach +-x, +-y
constexpr int kStacks = 12;  // even: a sphere has an equator ring

Eigen::Isometry3d ToIsometry(const Pose& pose) {
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.linear() = pose.orientation.normalized().toRotationMatrix();
  t.translation() = pose.position_mm;
  return t;
}

// A rounded triangle: the two faces offset by the half-thickness, a cylinder along each edge and
// a sphere at each corner (the Minkowski sum of the triangle and a ball, tessellated).
void RoundedTriangle(MeshBuilder* b, const InstrumentPart& p) {
  const Vec3 n = (p.v[1] - p.v[0]).cross(p.v[2] - p.v[0]).normalized();
  b->Sphere(p.v[0], Vec3::Constant(p.radius_mm), kStacks / 2, kSides / 2);
  for (int k = 0; k < 3; ++k) {
    const Vec3& a = p.v[static_cast<std::size_t>(k)];
    const Vec3& c = p.v[static_cast<std::size_t>((k + 1) % 3)];
    if (k > 0) b->Sphere(a, Vec3::Constant(p.radius_mm), kStacks / 2, kSides / 2);
    if ((c - a).norm() > 1e-9)
      b->Cylinder(a, c, p.radius_mm, p.radius_mm, kSides / 2, false, false);
  }
  for (const double s : {1.0, -1.0}) {
    const Vec3 off = s * p.radius_mm * n;
    b->Triangle(p.v[0] + off, s > 0 ? p.v[1] + off : p.v[2] + off,
                s > 0 ? p.v[2] + off : p.v[1] + off);
  }
}

// One part of the shared instrument description, drawn as what it is.
void DrawPart(MeshBuilder* b, const InstrumentPart& p) {
  const Vec3 r = Vec3::Constant(p.radius_mm);
  switch (p.n) {
    case 1:
      b->Sphere(p.v[0], r, kStacks, kSides);
      break;
    case 2:
      if ((p.v[1] - p.v[0]).norm() > 1e-9) {
        b->Cylinder(p.v[0], p.v[1], p.radius_mm, p.radius_mm, kSides, false, false);
      }
      b->Sphere(p.v[0], r, kStacks, kSides);
      b->Sphere(p.v[1], r, kStacks, kSides);
      break;
    default:
      if (p.radius_mm > 0) {
        RoundedTriangle(b, p);
      } else {  // a zero-thickness marking (shaver window): both sides
        b->Triangle(p.v[0], p.v[1], p.v[2]);
        b->Triangle(p.v[0], p.v[2], p.v[1]);
      }
      break;
  }
}

// Insulation and openings are dark; everything else is bare metal.
bool IsDark(InstrumentKind kind, const InstrumentPart& p) {
  return p.part == ToolPart::kShaverWindow ||
         (kind == InstrumentKind::kElectrocautery && p.part == ToolPart::kShaft);
}

}  // namespace

void AppendInstrument(const InstrumentModel& m, double jaw, const Pose& pose, SceneMesh* metal,
                      SceneMesh* dark) {
  const Eigen::Isometry3d frame = ToIsometry(pose);
  MeshBuilder b(metal, frame), d(dark, frame);
  const InstrumentParts parts = InstrumentPartsLocal(m, jaw);
  for (int i = 0; i < parts.count; ++i) {
    const InstrumentPart& p = parts.parts[static_cast<std::size_t>(i)];
    DrawPart(IsDark(m.kind, p) ? &d : &b, p);
  }
}

void AppendScope(const Pose& pose, double diameter_mm, SceneMesh* mesh) {
  MeshBuilder b(mesh, ToIsometry(pose));
  b.Cylinder(Vec3(0, 0, -150.0), Vec3::Zero(), 0.5 * diameter_mm, 0.5 * diameter_mm, kSides, true,
             true);
}

}  // namespace arthrosim::render
