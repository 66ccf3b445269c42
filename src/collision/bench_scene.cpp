#include "arthrosim/collision/bench_scene.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <string>
#include <vector>

#include "arthrosim/collision/contact_generation.h"
#include "arthrosim/core/parallel.h"
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
  m.bones.push_back(
      BoneModel{"humerus", "", Ellipsoid(Vec3::Zero(), Vec3(22, 22, 22), 60, 51), 1, {}, {}});
  m.bones.push_back(
      BoneModel{"acromion", "", Ellipsoid(Vec3(0, 0, 44), Vec3(14, 8, 3), 11, 7), 2, {}, {}});
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

namespace {

// Highest point of the soft bodies' rest boundaries above (x, y), mm; false if none is there.
struct TopSurface {
  std::vector<std::array<Vec3, 3>> tris;
  bool Z(double x, double y, double* z) const {
    bool found = false;
    for (const auto& t : tris) {
      const Vec3 &a = t[0], &b = t[1], &c = t[2];
      const double d = (b.x() - a.x()) * (c.y() - a.y()) - (c.x() - a.x()) * (b.y() - a.y());
      if (std::abs(d) < 1e-12) continue;
      const double u = ((b.x() - x) * (c.y() - y) - (c.x() - x) * (b.y() - y)) / d;
      const double v = ((c.x() - x) * (a.y() - y) - (a.x() - x) * (c.y() - y)) / d;
      if (u < 0 || v < 0 || u + v > 1) continue;
      const double h = u * a.z() + v * b.z() + (1 - u - v) * c.z();
      if (!found || h > *z) *z = h;
      found = true;
    }
    return found;
  }
};

// Thread CPU time, ms: unlike wall time it does not count other processes on a shared machine
// (but with worker threads it misses their share).
double CpuMs() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return 1e3 * static_cast<double>(ts.tv_sec) + 1e-6 * static_cast<double>(ts.tv_nsec);
}

// Wall time, ms.
double WallMs() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return 1e3 * static_cast<double>(ts.tv_sec) + 1e-6 * static_cast<double>(ts.tv_nsec);
}

// The instrument for a bench slot: a grasper in slot 0 and a shaver in slot 1 when the model
// has them (the usual pair in contact with the cuff), else instruments 0 and 1.
int BenchInstrument(const Model& model, int slot) {
  const InstrumentKind want = slot == 0 ? InstrumentKind::kGrasper : InstrumentKind::kShaver;
  for (std::size_t i = 0; i < model.instruments.size(); ++i) {
    if (model.instruments[i].kind == want) return static_cast<int>(i);
  }
  return slot < static_cast<int>(model.instruments.size()) ? slot : -1;
}

}  // namespace

CollisionBenchResult BenchmarkCollision(
    const Model& model, int steps,
    const std::function<void(int step, const CollisionOutput& out)>& on_step) {
  State state = MakeInitialState(model);
  std::vector<Points> rest;
  for (const SoftBodyState& b : state.soft_bodies) rest.push_back(b.x);
  // Work on the tendon if there is one (else soft body 0): its rest box and top surface.
  int target = 0;
  for (std::size_t b = 0; b < model.soft_bodies.size(); ++b) {
    if (model.soft_bodies[b].name.find("tendon") != std::string::npos) {
      target = static_cast<int>(b);
      break;
    }
  }
  TopSurface top;
  for (const SoftBodyState& b : state.soft_bodies) {
    for (const mesh::Tri& t : BoundaryTriangles(b.tets, b.tet_alive)) {
      top.tris.push_back({b.x.col(t[0]), b.x.col(t[1]), b.x.col(t[2])});
    }
  }
  Vec3 lo = Vec3::Constant(-10), hi = Vec3::Constant(10);
  if (!rest.empty() && rest[target].cols() > 0) {
    lo = rest[target].rowwise().minCoeff();
    hi = rest[target].rowwise().maxCoeff();
  }
  const Vec3 mid = 0.5 * (lo + hi), size = hi - lo;
  auto surface_z = [&](double x, double y, double fallback) {
    double z = fallback;
    return top.Z(x, y, &z) ? z : fallback;
  };
  // Thread 0 lies on the tissue along x through the middle of the target, from its lateral
  // (+x) end medially, 0.05 mm above the surface (within the alarm distance: in contact).
  if (!state.threads.empty()) {
    ThreadState& th = state.threads[0];
    const double r = 0.5 * model.threads[0].diameter_mm;
    double seg = 1.0;
    if (th.x.cols() > 1) seg = (th.x.col(1) - th.x.col(0)).norm();
    double z = hi.z();
    for (Eigen::Index i = 0; i < th.x.cols(); ++i) {
      const double x = hi.x() - 1.0 - seg * static_cast<double>(i);
      z = surface_z(x, mid.y(), z);
      th.x.col(i) = Vec3(x, mid.y(), z + r + 0.05);
    }
  }
  // Tools: tips 0.5 mm inside the top surface, shafts coming from above, tilted 30 degrees
  // toward their portal's side (a straight line from a portal could run through the cuff), moving
  // across the thread along y at 100 mm/s in opposite phase.
  std::array<Quat, kToolSlots> orient;
  std::array<double, kToolSlots> xs{mid.x() - 0.25 * size.x(), mid.x() + 0.25 * size.x()};
  for (int slot = 0; slot < kToolSlots; ++slot) {
    ToolState& t = state.tools[slot];
    t.instrument = BenchInstrument(model, slot);
    Vec3 dir = -Vec3::UnitZ();
    if (t.instrument >= 0) {
      const int p = model.FindPortal(model.instruments[t.instrument].portal);
      Vec3 side = p >= 0 ? Vec3(Vec3(xs[slot], mid.y(), 0) - model.portals[p].position_mm)
                         : Vec3(Vec3::Zero());
      side.z() = 0;
      if (side.norm() > 1.0) dir = (-Vec3::UnitZ() + std::tan(units::kPi / 6) * side.normalized());
      dir.normalize();
    }
    orient[slot] = Quat::FromTwoVectors(Vec3::UnitZ(), dir);
  }
  const double dt = 0.02, speed = 100.0;
  const double half = std::max(0.3 * size.y(), 1.0);
  const CollisionParams params = ParamsFromModel(model.contact);
  CollisionWorld world;
  CollisionOutput out;
  std::vector<double> ms;
  double contacts = 0;
  for (int s = 0; s < steps; ++s) {
    const std::array<ToolState, kToolSlots> prev = state.tools;
    // Triangle wave along y at 100 mm/s.
    const double travel = std::fmod(speed * dt * s, 4 * half);
    const double w = travel < 2 * half ? -half + travel : 3 * half - travel;
    for (int slot = 0; slot < kToolSlots; ++slot) {
      ToolState& t = state.tools[slot];
      const double y = mid.y() + (slot == 0 ? w : -w);
      t.pose.position_mm = Vec3(xs[slot], y, surface_z(xs[slot], y, hi.z()) - 0.5);
      t.pose.orientation = orient[slot];
      t.jaw = 0.5 + 0.5 * std::sin(0.1 * s);
    }
    // A small travelling wave on the soft bodies so the trees are refit every step.
    for (std::size_t b = 0; b < state.soft_bodies.size(); ++b) {
      Points& px = state.soft_bodies[b].x;
      for (Eigen::Index i = 0; i < px.cols(); ++i) {
        px(2, i) = rest[b](2, i) + 0.3 * std::sin(0.2 * rest[b](0, i) + 0.3 * s);
      }
    }
    const double c0 = CpuMs(), w0 = WallMs();
    Detect(model, state, s == 0 ? state.tools : prev, params, &world, &out);
    const double w1 = WallMs(), c1 = CpuMs();
    // One thread: the thread's CPU time (immune to other processes); with workers: wall time.
    ms.push_back(ThreadCount() > 1 ? w1 - w0 : c1 - c0);
    contacts += static_cast<double>(out.contacts.size());
    if (on_step) on_step(s, out);
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
  r.threads = ThreadCount();
  return r;
}

std::string FormatCollisionBench(const CollisionBenchResult& r) {
  char buf[256];
  std::snprintf(buf, sizeof buf,
                "collision_ms_median=%.4f\ncollision_ms_p90=%.4f\ncollision_contacts_mean=%.1f\n"
                "collision_rebuilds=%lld\ncollision_threads=%d\n",
                r.median_ms, r.p90_ms, r.mean_contacts, static_cast<long long>(r.rebuilds),
                r.threads);
  return buf;
}

}  // namespace arthrosim::collision
