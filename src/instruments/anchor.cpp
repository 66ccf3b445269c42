// Anchor: button 2 of the awl in a hole at least operations.anchor.min_hole_depth_mm deep seats
// a suture anchor at the bottom of the hole: a rigid body fixed to the bone (State::anchors).
// The sutures the anchor carries (operations.anchor.sutures, out of the scene until now) are laid
// from its eyelet up the hole and out, their first node held to the anchor by a stiff spring.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>

#include "arthrosim/physics/constraints.h"
#include "operations.h"

namespace arthrosim::instruments {
namespace {

bool HasAnchor(const State& state, int hole) {
  return std::any_of(state.anchors.begin(), state.anchors.end(),
                     [&](const AnchorState& a) { return a.hole == hole; });
}

// A unit vector orthogonal to `axis` (deterministic choice).
Vec3 Across(const Vec3& axis) {
  const Vec3 ref = std::abs(axis.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitY();
  return axis.cross(ref).normalized();
}

// Lays thread `t` from `eyelet` back up the hole axis to the entry, then on in the thread's
// initial shape (translated), every segment at its rest length; all nodes alive, at rest.
void LaySuture(const Model& model, int t, const Vec3& eyelet, const AnchorState& a, State* state) {
  const Points& init = model.threads[static_cast<std::size_t>(t)].initial.nodes;
  ThreadState& th = state->threads[static_cast<std::size_t>(t)];
  const int n = static_cast<int>(init.cols());
  th.x.resize(3, n);
  th.x.col(0) = eyelet;
  double arc = 0;
  int k = 0;
  while (k + 1 < n && arc < a.depth_mm) {
    arc += (init.col(k + 1) - init.col(k)).norm();
    th.x.col(k + 1) = eyelet - arc * a.axis;
    ++k;
  }
  for (int i = k + 1; i < n; ++i) th.x.col(i) = th.x.col(k) + (init.col(i) - init.col(k));
  th.v = Points::Zero(3, n);
  th.node_alive.assign(static_cast<std::size_t>(n), 1);
}

void HoldToAnchor(int t, const Vec3& eyelet, const AnchorState& a, double stiffness, State* state) {
  SpringConstraint c;
  c.tag = "anchor";
  c.a.kind = ConstraintEnd::Kind::kThread;
  c.a.index = t;
  c.a.nodes = {0, -1, -1, -1};
  c.a.weights = {1, 0, 0, 0};
  c.b.kind = ConstraintEnd::Kind::kBone;
  c.b.index = a.bone;
  c.b.offset_mm = eyelet;
  c.stiffness_n_per_mm = stiffness;
  c.rest_length_mm = 0;
  physics::AddConstraint(state, c);
}

}  // namespace

int HoleForAnchor(const Model& model, const Vec3& tip, const State& state) {
  const AnchorOptions& opt = model.operations.anchor;
  int best = -1;
  double best_d = opt.capture_radius_mm;
  for (std::size_t h = 0; h < state.holes.size(); ++h) {
    const BoneHole& hole = state.holes[h];
    if (hole.depth_mm < opt.min_hole_depth_mm || HasAnchor(state, static_cast<int>(h))) continue;
    const Vec3 d = tip - hole.entry_mm;
    const double s = std::clamp(d.dot(hole.axis), 0.0, hole.depth_mm);
    const double dist = (d - s * hole.axis).norm();
    if (dist <= best_d) {
      best_d = dist;
      best = static_cast<int>(h);
    }
  }
  return best;
}

void SeatAnchor(const Model& model, int slot, int hole, State* state) {
  const BoneHole& h = state->holes[static_cast<std::size_t>(hole)];
  AnchorState a;
  a.bone = h.bone;
  a.hole = hole;
  a.axis = h.axis;
  a.depth_mm = h.depth_mm;
  a.position_mm = h.entry_mm + h.depth_mm * h.axis;
  a.angle_deg = h.angle_deg;
  const bool first = state->anchors.empty();
  state->anchors.push_back(a);
  // The first anchor carries the scene's anchor sutures, their eyelets side by side.
  int limbs = 0;
  if (first) {
    const std::vector<std::string>& names = model.operations.anchor.sutures;
    const Vec3 across = Across(a.axis);
    for (std::size_t i = 0; i < names.size(); ++i) {
      const int t = model.FindThread(names[i]);
      if (t < 0) continue;
      const double side = names.size() > 1 ? (i % 2 == 0 ? 0.3 : -0.3) : 0.0;
      const Vec3 eyelet = a.position_mm + side * across;
      LaySuture(model, t, eyelet, a, state);
      HoldToAnchor(t, eyelet, a, model.operations.anchor.stiffness_n_per_mm, state);
      ++limbs;
    }
  }
  char buf[256];
  std::snprintf(buf, sizeof buf,
                "anchor=%d hole=%d depth_mm=%.6g angle_deg=%.6g limbs=%d axis=%.6g,%.6g,%.6g",
                static_cast<int>(state->anchors.size()) - 1, hole, a.depth_mm, a.angle_deg, limbs,
                a.axis.x(), a.axis.y(), a.axis.z());
  RecordEvent(model, slot, "anchor", model.bones[static_cast<std::size_t>(a.bone)].name, buf,
              a.position_mm, state);
}

}  // namespace arthrosim::instruments
