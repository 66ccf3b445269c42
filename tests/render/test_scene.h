#pragma once
// Hand-built scenes for the render tests: a few tets, a bone sphere, a thread, an instrument and
// the scope, independent of the anatomy files.
#include <cmath>
#include <cstdlib>
#include <numbers>

#include "arthrosim/core/model.h"
#include "arthrosim/core/state.h"
#include "arthrosim/render/renderer.h"
#include "arthrosim/render/scene.h"
#include "arthrosim/render/synthetic_scene.h"

namespace arthrosim::render::testing {

inline constexpr double kPi = std::numbers::pi;

/// Pins llvmpipe's rasteriser threads before the first context (deterministic images).
inline void PinLlvmpipeThreads() { setenv("LP_NUM_THREADS", "2", 1); }

/// One renderer (one OSMesa context) for every render test of the process, made on first use.
inline Renderer& SharedRenderer() {
  PinLlvmpipeThreads();
  static Renderer renderer;
  return renderer;
}

/// Closed UV sphere, outward.
inline mesh::TriMesh UvSphere(const Vec3& c, double r, int n) {
  return UvEllipsoid(c, Vec3(r, r, r), n);
}

/// A cube [lo, lo + edge]^3 cut into 5 positive tets.
inline mesh::TetMesh FiveTetCube(const Vec3& lo, double edge) {
  mesh::TetMesh m;
  m.nodes.resize(3, 8);
  for (int b = 0; b < 8; ++b) {
    m.nodes.col(b) = lo + edge * Vec3(b & 1, (b >> 1) & 1, (b >> 2) & 1);
  }
  // corner tets at 0, 3, 5, 6 and the central one, each positively oriented
  m.tets = {{0, 1, 2, 4}, {3, 2, 1, 7}, {5, 4, 7, 1}, {6, 7, 4, 2}, {1, 2, 7, 4}};
  for (auto& t : m.tets) {
    const Vec3 p0 = m.nodes.col(t[0]);
    if ((m.nodes.col(t[1]) - p0).dot((m.nodes.col(t[2]) - p0).cross(m.nodes.col(t[3]) - p0)) < 0) {
      std::swap(t[2], t[3]);
    }
  }
  return m;
}

/// An instrument named `name` of `kind`, its shape the default.
inline InstrumentModel NamedInstrument(const char* name, InstrumentKind kind) {
  InstrumentModel m;
  m.name = name;
  m.kind = kind;
  return m;
}

inline Pose ToolPose(const Vec3& tip, const Vec3& forward) {
  Pose p;
  p.position_mm = tip;
  p.orientation = Quat::FromTwoVectors(Vec3::UnitZ(), forward.normalized());
  return p;
}

/// Scene: tendon block (5 tets, 8 mm) and a bone sphere below it, a thread across, a grasper;
/// the scope 25 mm away looking at the block's top face centre (0, 0, 8).
inline State MakeTestScene(Model* model) {
  *model = Model{};
  model->name = "render_test";
  SoftBodyModel tendon;
  tendon.name = "tendon";
  tendon.rest_mesh = FiveTetCube(Vec3(-4, -4, 0), 8.0);
  model->soft_bodies = {tendon};
  BoneModel bone;
  bone.name = "humerus";
  bone.surface = UvSphere(Vec3(0, 0, -12), 12.0, 12);
  model->bones = {bone};
  ThreadModel thread;
  thread.name = "suture";
  thread.initial.nodes.resize(3, 12);
  for (int i = 0; i < 12; ++i) {
    thread.initial.nodes.col(i) = Vec3(-9 + 1.6 * i, -2 + 0.2 * i, 8.6 + 0.05 * i * i);
    if (i > 0) thread.initial.edges.push_back({i - 1, i});
  }
  model->threads = {thread};
  InstrumentModel burr = NamedInstrument("burr", InstrumentKind::kBurr);
  burr.shaft_diameter_mm = 2.0;
  burr.tip_radius_mm = 3.0;
  burr.tip_length_mm = 6.0;
  model->instruments = {NamedInstrument("grasper", InstrumentKind::kGrasper), burr};
  model->camera.initial_pose =
      AimScope(Vec3(0, -15, 28), Vec3(0, 0, 8), Vec3::UnitZ(), 30 * kPi / 180);
  State state = MakeInitialState(*model);
  state.time_s = 1.25;
  state.tools[0].instrument = 0;
  state.tools[0].pose = ToolPose(Vec3(4, 1, 12), Vec3(-1, 0.3, -0.4));
  state.tools[0].jaw = 0.3;
  state.tools[0].force_n = Vec3(0, 3, 4);  // 5 N
  return state;
}

}  // namespace arthrosim::render::testing
