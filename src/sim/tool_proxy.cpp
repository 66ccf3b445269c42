#include "arthrosim/sim/tool_proxy.h"

#include <algorithm>
#include <cmath>

namespace arthrosim::sim {
namespace {

// Query reach of the clearance search, mm: a free proxy advances at most this far per
// iteration (conservative advancement: a tool that clears bone by c can move c safely).
constexpr double kReachMm = 4.0;
// Smallest advance per iteration near bone, mm (then checked and pushed out if it overlaps).
constexpr double kMinAdvanceMm = 0.25;
// Clearance the push-out leaves between tool and bone, mm.
constexpr double kSkinMm = 1e-3;
// Bounds on the work per slot and step.
constexpr int kMaxIterations = 96;
constexpr int kMaxPushes = 4;
// Motion below this (mm) counts as arrived / stuck.
constexpr double kArrivedMm = 1e-6;
// Soft tissue trapped against bone: when the instrument is within kTrappedMm of bone and pressed
// tissue toward it last step with more than kTissueTouchN, it advances toward the bone at most
// kTissueAdvanceMm per step, not at all once the reaction reaches the device maximum (the hand
// cannot push harder than that), and never closer to bone than haptics.trapped_gap_mm: the
// tissue between is pressed to at most that thickness, never crushed through. Along the bone it
// slides only where the hand's sideways pull exceeds haptics.trapped_friction times its push
// toward the bone (Coulomb's cone), so tissue pressed against bone is not dragged away by a hand
// that pushes into it. kTrappedMm is about the thickness of the cuff tendon.
constexpr double kTrappedMm = 6.0;
constexpr double kTissueTouchN = 0.05;
constexpr double kTissueAdvanceMm = 0.5;

// Largest distance of a point of the instrument's contacting parts from the tip, mm: a rotation
// by angle a moves no such point farther than a times this.
double LeverArm(const std::vector<collision::ToolPrimitive>& local) {
  double arm = 0;
  for (const collision::ToolPrimitive& p : local) {
    for (int i = 0; i < p.core.n; ++i) arm = std::max(arm, p.core.v[i].norm() + p.radius_mm);
  }
  return arm;
}

// Bound on the displacement of any instrument point between two poses, mm.
double Motion(const Pose& a, const Pose& b, double arm) {
  return (b.position_mm - a.position_mm).norm() +
         a.orientation.angularDistance(b.orientation) * arm;
}

Pose Interpolate(const Pose& a, const Pose& b, double t) {
  Pose p;
  p.position_mm = a.position_mm + t * (b.position_mm - a.position_mm);
  p.orientation = a.orientation.slerp(t, b.orientation);
  p.orientation.normalize();
  return p;
}

collision::ToolBoneHit Clearance(const Model& model, ToolState tool, const Pose& pose,
                                 ProxyWorkspace* ws) {
  tool.pose = pose;
  collision::ToolPrimitivesWorld(model, tool, &ws->primitives);
  return collision::ToolBoneClearance(ws->primitives, kReachMm, &ws->bones);
}

// Pushes `pose` out of bone along the reported way out; false if it is still inside after
// kMaxPushes tries.
bool PushOut(const Model& model, const ToolState& tool, Pose* pose, collision::ToolBoneHit* hit,
             ProxyWorkspace* ws) {
  for (int k = 0; k < kMaxPushes && hit->clearance_mm < 0; ++k) {
    pose->position_mm += (kSkinMm - hit->clearance_mm) * hit->normal;
    *hit = Clearance(model, tool, *pose, ws);
  }
  return hit->clearance_mm >= 0;
}

// Where a newly inserted instrument starts: at its handle if clear of bone (and not inside it),
// else at its portal with the handle's orientation.
Pose StartPose(const Model& model, const ToolState& tool, ProxyWorkspace* ws) {
  const collision::ToolBoneHit at_handle = Clearance(model, tool, tool.handle_pose, ws);
  if (at_handle.clearance_mm >= 0 &&
      collision::PointBoneSignedDistance(tool.handle_pose.position_mm, &ws->bones) > 0) {
    return tool.handle_pose;
  }
  const InstrumentModel& im = model.instruments[static_cast<std::size_t>(tool.instrument)];
  const int portal = model.FindPortal(im.portal);
  if (portal < 0) return tool.handle_pose;
  Pose start = tool.handle_pose;
  start.position_mm = model.portals[static_cast<std::size_t>(portal)].position_mm;
  return start;
}

// The earlier rule (haptics.trapped_gap_mm = 0): the advance along the way the tissue was pushed
// is bounded per step and stops at the device maximum; no floor, free sliding.
Vec3 AdvanceLimitedGoal(const Model& model, double magnitude, const Vec3& into, const Pose& from,
                        const Vec3& handle) {
  const Vec3 d = handle - from.position_mm;
  const double advance = d.dot(into);
  const double allowed = magnitude >= model.haptics.max_force_n ? 0.0 : kTissueAdvanceMm;
  if (advance <= allowed) return handle;
  return handle - (advance - allowed) * into;
}

// The trapped-tissue rule: the way toward the bone (along its normal at the nearest point) is
// bounded per step and by the floor haptics.trapped_gap_mm, the way along it held by friction.
Vec3 FloorAndFrictionGoal(const Model& model, double magnitude, const collision::ToolBoneHit& near,
                          const Pose& from, const Vec3& handle) {
  const HapticsOptions& h = model.haptics;
  const Vec3& out = near.normal;  // away from the bone
  const Vec3 d = handle - from.position_mm;
  const double press = -d.dot(out);  // the hand's way toward the bone, mm
  if (press <= 0) return handle;     // drawn away from the bone: free
  const Vec3 along = d + press * out;
  const double floor_mm = std::max(0.0, near.clearance_mm - h.trapped_gap_mm);
  const double allowed = magnitude >= h.max_force_n ? 0.0 : std::min(kTissueAdvanceMm, floor_mm);
  const double along_mm = along.norm();
  const double slide_mm = std::max(0.0, along_mm - h.trapped_friction * press);
  Vec3 goal = from.position_mm - std::min(press, allowed) * out;
  if (along_mm > 0) goal += along * (slide_mm / along_mm);
  return goal;
}

// The handle position the proxy may head for this step when it pressed soft tissue toward bone
// last step (see kTrappedMm); the handle itself otherwise.
Vec3 TissueLimitedGoal(const Model& model, const ToolState& prev, const Pose& from,
                       const Vec3& handle, ProxyWorkspace* ws) {
  if (prev.instrument < 0) return handle;
  const Vec3& tissue_n = prev.tissue_force_n;
  const double magnitude = tissue_n.norm();
  if (magnitude <= kTissueTouchN) return handle;
  const Vec3 into = -tissue_n / magnitude;  // the way the instrument pushed the tissue
  const collision::ToolBoneHit near = Clearance(model, prev, from, ws);
  if (near.bone < 0 || near.clearance_mm >= kTrappedMm || into.dot(near.normal) >= 0) {
    return handle;  // no bone behind the tissue: the tissue can give way
  }
  if (model.haptics.trapped_gap_mm <= 0) {
    return AdvanceLimitedGoal(model, magnitude, into, from, handle);
  }
  return FloorAndFrictionGoal(model, magnitude, near, from, handle);
}

// Follows the handle from `from` by conservative advancement: steps no longer than the current
// clearance (or kMinAdvanceMm near bone), each pushed out of bone if it overlaps; stops at the
// handle, when stuck (no progress: the handle lies behind the surface), or after kMaxIterations.
Pose Follow(const Model& model, const ToolState& tool, const Pose& from, const Pose& goal,
            double arm, collision::ToolBoneHit* hit, int* iterations, ProxyWorkspace* ws) {
  Pose cur = from;
  *hit = Clearance(model, tool, cur, ws);
  if (hit->clearance_mm < 0 && !PushOut(model, tool, &cur, hit, ws)) return cur;
  int it = 0;
  for (; it < kMaxIterations; ++it) {
    const double remaining = Motion(cur, goal, arm);
    if (remaining <= kArrivedMm) break;
    const double advance = std::max(hit->clearance_mm, kMinAdvanceMm);
    Pose next = Interpolate(cur, goal, std::min(1.0, advance / remaining));
    collision::ToolBoneHit h = Clearance(model, tool, next, ws);
    if (h.clearance_mm < 0 && !PushOut(model, tool, &next, &h, ws)) break;
    const double progress = Motion(cur, next, arm);
    cur = next;
    *hit = h;
    if (progress <= kArrivedMm) break;
  }
  *iterations = it;
  return cur;
}

}  // namespace

void ResolveToolProxies(const Model& model, const std::array<ToolState, kToolSlots>& prev_tools,
                        State* state, ProxyWorkspace* ws) {
  ws->touches.clear();
  ws->iterations.fill(0);
  if (model.haptics.proxy) collision::SyncBoneQuery(*state, &ws->bones);
  for (int slot = 0; slot < kToolSlots; ++slot) {
    ToolState& tool = state->tools[static_cast<std::size_t>(slot)];
    if (!model.haptics.proxy || tool.instrument < 0) {
      tool.pose = tool.handle_pose;
      continue;
    }
    const ToolState& prev = prev_tools[static_cast<std::size_t>(slot)];
    const InstrumentModel& im = model.instruments[static_cast<std::size_t>(tool.instrument)];
    collision::InstrumentPrimitivesLocal(im, tool.jaw, &ws->primitives);
    const double arm = LeverArm(ws->primitives);
    const bool same = prev.instrument == tool.instrument;
    const Pose from = same ? prev.pose : StartPose(model, tool, ws);
    Pose goal = tool.handle_pose;
    if (same) goal.position_mm = TissueLimitedGoal(model, prev, from, goal.position_mm, ws);
    collision::ToolBoneHit hit;
    tool.pose = Follow(model, tool, from, goal, arm, &hit, &ws->iterations[slot], ws);
    if (hit.bone >= 0 && hit.clearance_mm < model.contact.contact_distance_mm) {
      ws->touches.push_back(ToolContact{slot, ConstraintEnd::Kind::kBone, hit.bone, hit.point_mm});
    }
  }
}

Vec3 CouplingForce(const Model& model, const ToolState& prev, const ToolState& now) {
  if (now.instrument < 0) return Vec3::Zero();
  const HapticsOptions& h = model.haptics;
  const Vec3 offset = now.pose.position_mm - now.handle_pose.position_mm;
  Vec3 f = h.coupling_stiffness_n_per_mm * offset;
  if (prev.instrument == now.instrument && model.options.dt_s > 0) {
    const Vec3 prev_offset = prev.pose.position_mm - prev.handle_pose.position_mm;
    f += h.coupling_damping_n_s_per_mm * (offset - prev_offset) / model.options.dt_s;
  }
  return f;
}

Vec3 ClampForce(const Vec3& f, double max_force_n) {
  const double n = f.norm();
  return n > max_force_n ? Vec3(f * (max_force_n / n)) : f;
}

}  // namespace arthrosim::sim
