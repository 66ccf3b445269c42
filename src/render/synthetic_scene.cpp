#include "arthrosim/render/synthetic_scene.h"

#include <cmath>
#include <numbers>

#include "arthrosim/render/scene.h"

namespace arthrosim::render {
namespace {

constexpr double kPi = std::numbers::pi;

// A curved slab of cells x cells x cells hexahedra (5 tets each, alternating so that the
// faces match) lying on a sphere of radius r0 (thickness t) around `centre`.
mesh::TetMesh CurvedSlab(const Vec3& centre, double r0, double t, int nx, int ny, int nz) {
  mesh::TetMesh m;
  const int px = nx + 1, py = ny + 1, pz = nz + 1;
  m.nodes.resize(3, px * py * pz);
  auto id = [&](int i, int j, int k) { return (k * py + j) * px + i; };
  for (int k = 0; k < pz; ++k) {
    for (int j = 0; j < py; ++j) {
      for (int i = 0; i < px; ++i) {
        // longitude from x, latitude from y, both within ~+-45 deg of the top
        const double a = (double(i) / nx - 0.5) * 1.6, b = (double(j) / ny - 0.5) * 1.1;
        const double r = r0 + t * k / nz;
        const Vec3 dir(std::sin(a) * std::cos(b), std::sin(b), std::cos(a) * std::cos(b));
        m.nodes.col(id(i, j, k)) = centre + r * dir;
      }
    }
  }
  static constexpr int kEven[5][4] = {
      {0, 1, 2, 4}, {3, 1, 7, 2}, {5, 1, 4, 7}, {6, 2, 7, 4}, {1, 2, 4, 7}};
  static constexpr int kOdd[5][4] = {
      {1, 0, 5, 3}, {2, 0, 3, 6}, {4, 0, 6, 5}, {7, 3, 5, 6}, {0, 3, 6, 5}};
  for (int k = 0; k < nz; ++k) {
    for (int j = 0; j < ny; ++j) {
      for (int i = 0; i < nx; ++i) {
        std::int32_t c[8];
        for (int b = 0; b < 8; ++b) c[b] = id(i + (b & 1), j + ((b >> 1) & 1), k + ((b >> 2) & 1));
        const auto& pattern = ((i + j + k) % 2 == 0) ? kEven : kOdd;
        for (const auto& tet : pattern) {
          mesh::Tet t{c[tet[0]], c[tet[1]], c[tet[2]], c[tet[3]]};
          const Vec3 p0 = m.nodes.col(t[0]);
          const double vol =
              (m.nodes.col(t[1]) - p0).dot((m.nodes.col(t[2]) - p0).cross(m.nodes.col(t[3]) - p0));
          if (vol < 0) std::swap(t[2], t[3]);
          m.tets.push_back(t);
        }
      }
    }
  }
  return m;
}

Pose ToolPose(const Vec3& tip, const Vec3& forward) {
  Pose p;
  p.position_mm = tip;
  p.orientation = Quat::FromTwoVectors(Vec3::UnitZ(), forward.normalized());
  return p;
}

}  // namespace

mesh::TriMesh UvEllipsoid(const Vec3& centre, const Vec3& radii, int n) {
  mesh::TriMesh m;
  const int slices = 2 * n, rings = n - 1;
  m.nodes.resize(3, 2 + rings * slices);
  m.nodes.col(0) = centre + Vec3(0, 0, radii.z());
  for (int j = 0; j < rings; ++j) {
    const double phi = kPi * (j + 1) / n;
    for (int i = 0; i < slices; ++i) {
      const double th = 2 * kPi * i / slices;
      m.nodes.col(1 + j * slices + i) =
          centre + radii.cwiseProduct(Vec3(std::sin(phi) * std::cos(th),
                                           std::sin(phi) * std::sin(th), std::cos(phi)));
    }
  }
  const int south = 1 + rings * slices;
  m.nodes.col(south) = centre - Vec3(0, 0, radii.z());
  auto v = [&](int j, int i) { return 1 + j * slices + (i % slices); };
  for (int i = 0; i < slices; ++i) m.tris.push_back({0, v(0, i), v(0, i + 1)});
  for (int j = 0; j + 1 < rings; ++j) {
    for (int i = 0; i < slices; ++i) {
      m.tris.push_back({v(j, i), v(j + 1, i), v(j + 1, i + 1)});
      m.tris.push_back({v(j, i), v(j + 1, i + 1), v(j, i + 1)});
    }
  }
  for (int i = 0; i < slices; ++i) m.tris.push_back({south, v(rings - 1, i + 1), v(rings - 1, i)});
  return m;
}

State MakeSyntheticScene(const SyntheticSceneSize& size, Model* model) {
  *model = Model{};
  model->name = "synthetic_shoulder";
  const Vec3 head(0, 0, 0);
  const double head_r = 22;

  BoneModel humerus;
  humerus.name = "humerus";
  humerus.surface = UvEllipsoid(head, Vec3(head_r, head_r, head_r), size.bone_subdivisions);
  BoneModel acromion;
  acromion.name = "acromion";
  acromion.surface = UvEllipsoid(Vec3(-4, 6, 36), Vec3(22, 12, 5), size.bone_subdivisions);
  model->bones = {humerus, acromion};

  SoftBodyModel tendon;
  tendon.name = "supraspinatus_tendon";
  tendon.rest_mesh = CurvedSlab(head, head_r + 0.3, 3.0, size.tendon_cells_x, size.tendon_cells_y,
                                size.tendon_cells_z);
  model->soft_bodies = {tendon};

  ThreadModel suture;
  suture.name = "suture";
  const int nodes = 41;
  suture.initial.nodes.resize(3, nodes);
  for (int i = 0; i < nodes; ++i) {
    const double s = double(i) / (nodes - 1);
    suture.initial.nodes.col(i) = Vec3(-8 + 20 * s, -6 + 4 * std::sin(3 * s), 26.5 + 4 * s * s);
    if (i > 0) suture.initial.edges.push_back({i - 1, i});
  }
  model->threads = {suture};

  InstrumentModel grasper;
  grasper.name = "grasper";
  grasper.kind = InstrumentKind::kGrasper;
  InstrumentModel shaver;
  shaver.name = "shaver";
  shaver.kind = InstrumentKind::kShaver;
  shaver.shaft_diameter_mm = 5.5;
  model->instruments = {grasper, shaver};

  const Vec3 target(0, 0, head_r + 2);
  model->camera.initial_pose =
      AimScope(Vec3(0, -32, 34), target, Vec3::UnitZ(), model->camera.lens_angle_deg * kPi / 180);

  State state = MakeInitialState(*model);
  state.tools[0].instrument = 0;
  state.tools[0].pose = ToolPose(target + Vec3(5, -3, 5), Vec3(-1, 0.6, -0.5));
  state.tools[0].jaw = 0.4;
  state.tools[0].force_n = Vec3(1.5, 0.5, 2.0);
  state.tools[1].instrument = 1;
  state.tools[1].pose = ToolPose(target + Vec3(-7, -4, 5), Vec3(1, 0.5, -0.6));
  return state;
}

}  // namespace arthrosim::render
