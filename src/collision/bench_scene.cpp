#include "arthrosim/collision/bench_scene.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <vector>

#include "arthrosim/collision/contact_generation.h"
#include "arthrosim/core/state.h"
#include "arthrosim/core/units.h"

namespace arthrosim::collision {

mesh::TetMesh BoxTets(const Vec3& lo, const Vec3& hi, int nx, int ny, int nz) {
  mesh::TetMesh m;
  const int px = nx + 1, py = ny + 1, pz = nz + 1;
  m.nodes.resize(3, px * py * pz);
  auto id = [&](int i, int j, int k) { return (k * py + j) * px + i; };
  for (int k = 0; k < pz; ++k)
    for (int j = 0; j < py; ++j)
      for (int i = 0; i < px; ++i) {
        m.nodes.col(id(i, j, k)) = lo + Vec3(i * (hi.x() - lo.x()) / nx, j * (hi.y() - lo.y()) / ny,
                                             k * (hi.z() - lo.z()) / nz);
      }
  // Freudenthal split of each cube along its main diagonal (conforming across cubes).
  const int paths[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  for (int k = 0; k < nz; ++k)
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i)
        for (const auto& path : paths) {
          int c[3] = {i, j, k};
          mesh::Tet t;
          t[0] = id(c[0], c[1], c[2]);
          for (int s = 0; s < 3; ++s) {
            ++c[path[s]];
            t[s + 1] = id(c[0], c[1], c[2]);
          }
          const Vec3 p0 = m.nodes.col(t[0]);
          if ((m.nodes.col(t[1]) - p0).dot((m.nodes.col(t[2]) - p0).cross(m.nodes.col(t[3]) - p0)) <
              0) {
            std::swap(t[2], t[3]);
          }
          m.tets.push_back(t);
        }
  return m;
}

mesh::TriMesh Ellipsoid(const Vec3& center, const Vec3& radii, int nu, int nv) {
  mesh::TriMesh m;
  // Node 0 = south pole, then (nv - 2) rings of nu nodes, then the north pole.
  const int rings = nv - 2;
  m.nodes.resize(3, 2 + rings * nu);
  m.nodes.col(0) = center - Vec3(0, 0, radii.z());
  for (int r = 0; r < rings; ++r) {
    const double th = units::kPi * (r + 1) / (nv - 1) - 0.5 * units::kPi;
    for (int u = 0; u < nu; ++u) {
      const double ph = 2 * units::kPi * u / nu;
      m.nodes.col(1 + r * nu + u) =
          center + Vec3(radii.x() * std::cos(th) * std::cos(ph),
                        radii.y() * std::cos(th) * std::sin(ph), radii.z() * std::sin(th));
    }
  }
  const int top = 1 + rings * nu;
  m.nodes.col(top) = center + Vec3(0, 0, radii.z());
  auto ring = [&](int r, int u) { return 1 + r * nu + (u % nu); };
  for (int u = 0; u < nu; ++u) {
    m.tris.push_back({0, ring(0, u + 1), ring(0, u)});
    for (int r = 0; r + 1 < rings; ++r) {
      m.tris.push_back({ring(r, u), ring(r, u + 1), ring(r + 1, u + 1)});
      m.tris.push_back({ring(r, u), ring(r + 1, u + 1), ring(r + 1, u)});
    }
    m.tris.push_back({top, ring(rings - 1, u), ring(rings - 1, u + 1)});
  }
  return m;
}

Model MakeBenchmarkModel() {
  Model m;
  m.name = "collision_benchmark";
  auto soft = [&](const char* name, const Vec3& lo, const Vec3& hi, int nx, int ny, int nz) {
    SoftBodyModel b;
    b.name = name;
    b.rest_mesh = BoxTets(lo, hi, nx, ny, nz);
    m.soft_bodies.push_back(b);
  };
  // Supraspinatus resting on the humeral head (its lowest nodes slightly inside), deltoid above.
  soft("supraspinatus", Vec3(-20, -12, 21.5), Vec3(20, 12, 29.5), 12, 8, 4);
  soft("deltoid", Vec3(-18, -12, 33), Vec3(18, 12, 39), 10, 6, 3);
  m.bones.push_back(BoneModel{"humerus", "", Ellipsoid(Vec3::Zero(), Vec3(22, 22, 22), 60, 51), 1});
  m.bones.push_back(BoneModel{"acromion", "", Ellipsoid(Vec3(0, 0, 44), Vec3(14, 8, 3), 11, 7), 2});
  for (int t = 0; t < 2; ++t) {
    ThreadModel th;
    th.name = t == 0 ? "suture_a" : "suture_b";
    th.initial.nodes.resize(3, 60);
    for (int i = 0; i < 60; ++i) {
      th.initial.nodes.col(i) = Vec3(-30 + i, t == 0 ? -4 : 4, 29.5 + 0.5 * th.diameter_mm + 0.05);
      if (i > 0) th.initial.edges.push_back({i - 1, i});
    }
    m.threads.push_back(th);
  }
  InstrumentModel grasper;
  grasper.name = "grasper";
  grasper.kind = InstrumentKind::kGrasper;
  m.instruments.push_back(grasper);
  InstrumentModel shaver;
  shaver.name = "shaver";
  shaver.kind = InstrumentKind::kShaver;
  shaver.shaft_diameter_mm = 5.5;
  shaver.tip_radius_mm = 1.5;
  m.instruments.push_back(shaver);
  return m;
}

CollisionBenchResult BenchmarkCollision(const Model& model, int steps) {
  State state = MakeInitialState(model);
  const std::vector<Points> rest = [&] {
    std::vector<Points> r;
    for (const SoftBodyState& b : state.soft_bodies) r.push_back(b.x);
    return r;
  }();
  // Path of the tools: across the top of the first soft body, pointing down (tool +z = -z).
  Vec3 lo = Vec3::Constant(-10), hi = Vec3::Constant(10);
  if (!rest.empty() && rest[0].cols() > 0) {
    lo = rest[0].rowwise().minCoeff();
    hi = rest[0].rowwise().maxCoeff();
  }
  const Vec3 mid = 0.5 * (lo + hi);
  const Quat down(Eigen::AngleAxisd(units::kPi, Vec3::UnitX()));
  const double dt = 0.02, speed = 100.0;
  const double half = std::max(0.4 * (hi.x() - lo.x()), 1.0);
  CollisionParams params;
  CollisionWorld world;
  CollisionOutput out;
  std::vector<double> ms;
  double contacts = 0;
  for (int s = 0; s < steps; ++s) {
    const std::array<ToolState, kToolSlots> prev = state.tools;
    // Triangle wave along x at 100 mm/s.
    const double travel = std::fmod(speed * dt * s, 4 * half);
    const double x = travel < 2 * half ? -half + travel : 3 * half - travel;
    for (int slot = 0; slot < kToolSlots; ++slot) {
      ToolState& t = state.tools[slot];
      t.instrument = slot < static_cast<int>(model.instruments.size()) ? slot : -1;
      const double y = slot == 0 ? -0.25 * (hi.y() - lo.y()) : 0.25 * (hi.y() - lo.y());
      t.pose.position_mm = Vec3(mid.x() + (slot == 0 ? x : -x), mid.y() + y, hi.z() - 1.0);
      t.pose.orientation = down;
      t.jaw = 0.5 + 0.5 * std::sin(0.1 * s);
    }
    if (s == 0) {
      for (int slot = 0; slot < kToolSlots; ++slot) state.tools[slot].force_n.setZero();
    }
    for (std::size_t b = 0; b < state.soft_bodies.size(); ++b) {
      Points& px = state.soft_bodies[b].x;
      for (Eigen::Index i = 0; i < px.cols(); ++i) {
        px(2, i) = rest[b](2, i) + 0.3 * std::sin(0.2 * rest[b](0, i) + 0.3 * s);
      }
    }
    const auto t0 = std::chrono::steady_clock::now();
    Detect(model, state, s == 0 ? state.tools : prev, params, &world, &out);
    const auto t1 = std::chrono::steady_clock::now();
    ms.push_back(std::chrono::duration<double, std::milli>(t1 - t0).count());
    contacts += static_cast<double>(out.contacts.size());
  }
  CollisionBenchResult r;
  if (ms.empty()) return r;
  // Skip the first step (tree builds) in the statistics; it is reported as rebuilds.
  std::vector<double> sorted(ms.begin() + (ms.size() > 1 ? 1 : 0), ms.end());
  std::sort(sorted.begin(), sorted.end());
  r.median_ms = sorted[sorted.size() / 2];
  r.p90_ms = sorted[std::min(sorted.size() - 1, sorted.size() * 9 / 10)];
  r.mean_contacts = contacts / static_cast<double>(steps);
  r.rebuilds = world.rebuilds;
  return r;
}

}  // namespace arthrosim::collision
