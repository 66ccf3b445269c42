#include "arthrosim/sim/tool_proxy.h"

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>

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
constexpr int kMaxIterations = kProxyMaxIterations;
constexpr int kMaxPushes = 4;
// A step that cannot be pushed out of bone is retried this many times at half the length.
constexpr int kMaxHalvings = 3;
// Motion below this (mm) counts as arrived / stuck.
constexpr double kArrivedMm = 1e-6;
// A proxy found overlapping bone that no push-out frees (the sliding proxy wedged into a carved
// cavity) backs out along its shaft, the way it came in, in steps of kRetreatStepMm up to
// kMaxRetreatMm, to the first pose clear of bone.
constexpr double kRetreatStepMm = 0.5;
constexpr double kMaxRetreatMm = 20.0;
// A proxy jammed while its handle is clear of bone backs out to this clearance, mm.
constexpr double kJamRetreatClearanceMm = 1.0;
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

// Equality of every bit (0.0 and -0.0 differ, a NaN equals itself): two values that are the
// same bits lead every computation to the same bits.
bool SameBits(double a, double b) {
  std::uint64_t x = 0, y = 0;
  std::memcpy(&x, &a, sizeof x);
  std::memcpy(&y, &b, sizeof y);
  return x == y;
}

bool SameBits(const Vec3& a, const Vec3& b) {
  return SameBits(a.x(), b.x()) && SameBits(a.y(), b.y()) && SameBits(a.z(), b.z());
}

bool SameBits(const Pose& a, const Pose& b) {
  return SameBits(a.position_mm, b.position_mm) && SameBits(a.orientation.w(), b.orientation.w()) &&
         SameBits(a.orientation.vec(), b.orientation.vec());
}

bool SameBits(const collision::ToolBoneHit& a, const collision::ToolBoneHit& b) {
  return SameBits(a.clearance_mm, b.clearance_mm) && a.bone == b.bone &&
         a.primitive == b.primitive && SameBits(a.point_mm, b.point_mm) &&
         SameBits(a.normal, b.normal);
}

collision::ToolBoneHit Clearance(const Model& model, ToolState tool, const Pose& pose,
                                 ProxyWorkspace* ws) {
  tool.pose = pose;
  ++ws->clearance_queries;
  collision::ToolPrimitivesWorld(model, tool, &ws->primitives);
  return collision::ToolBoneClearance(ws->primitives, kReachMm, &ws->bones);
}

// Whether the instrument at `pose` is clear of bone by at least `min_clearance_mm` and its tip
// outside every bone (the clearance query looks only kReachMm deep: a pose deep inside a bone
// reads as clear), with the clearance in *hit.
bool ClearOfBone(const Model& model, const ToolState& tool, const Pose& pose,
                 double min_clearance_mm, collision::ToolBoneHit* hit, ProxyWorkspace* ws) {
  *hit = Clearance(model, tool, pose, ws);
  return hit->clearance_mm >= min_clearance_mm &&
         collision::PointBoneSignedDistance(pose.position_mm, &ws->bones) > 0;
}

// Where a newly inserted instrument starts: at its handle if clear of bone (and not inside it),
// else at its portal with the handle's orientation.
Pose StartPose(const Model& model, const ToolState& tool, ProxyWorkspace* ws) {
  collision::ToolBoneHit at_handle;
  if (ClearOfBone(model, tool, tool.handle_pose, 0.0, &at_handle, ws)) return tool.handle_pose;
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

// The bone surfaces the proxy met during one Follow, at most three (sliding along a crease
// between two surfaces, or stopping in a corner, needs them all), each as a plane in the space of
// the proxy's position: the tool touches surface k when its position x has x . n_k = level_k
// (n_k the outward normal met, level_k = p . n_k - clearance at the position p where it was met).
// Fixed storage: the step makes no heap allocation.
class ContactPlanes {
 public:
  // Adds the surface met at proxy position `position` with outward unit normal `normal` and the
  // clearance `clearance_mm` there (< 0: overlapping). A normal within ~2.5 degrees of one held
  // replaces it (the same surface, as met now); a fourth surface replaces the oldest.
  void Add(const Vec3& position, const Vec3& normal, double clearance_mm) {
    const Plane plane{normal, position.dot(normal) - clearance_mm};
    for (int k = 0; k < count_; ++k) {
      if (planes_[static_cast<std::size_t>(k)].normal.dot(normal) > kSameNormal) {
        planes_[static_cast<std::size_t>(k)] = plane;
        return;
      }
    }
    if (count_ == kMaxPlanes) {
      for (int k = 1; k < kMaxPlanes; ++k)
        planes_[static_cast<std::size_t>(k - 1)] = planes_[static_cast<std::size_t>(k)];
      --count_;
    }
    planes_[static_cast<std::size_t>(count_++)] = plane;
  }

  bool empty() const { return count_ == 0; }

  // Every plane held (and every unused slot) the same bits as in `o`.
  bool SameBits(const ContactPlanes& o) const {
    if (count_ != o.count_) return false;
    for (std::size_t k = 0; k < planes_.size(); ++k) {
      if (!sim::SameBits(planes_[k].normal, o.planes_[k].normal) ||
          !sim::SameBits(planes_[k].level_mm, o.planes_[k].level_mm)) {
        return false;
      }
    }
    return true;
  }

  // The part of the displacement `way` from position `cur` that does not lead closer than
  // kSkinMm to any surface held: the nearest x to `way` with x . n_k >= -gap_k, gap_k =
  // max(0, cur . n_k - level_k - kSkinMm) (the distance the proxy may still close toward surface
  // k; never negative, so x = 0 is feasible and |x - way| <= |way|: the result is bounded
  // however the surfaces lie). A quadratic program of at most three constraints,
  // solved exactly by trying every set of active constraints (at most 8) and keeping the
  // nearest feasible point; zero if none is feasible. Deterministic.
  Vec3 Admissible(const Vec3& cur, const Vec3& way) const {
    std::array<double, kMaxPlanes> gap{};
    for (int k = 0; k < count_; ++k) gap[static_cast<std::size_t>(k)] = std::max(0.0, Gap(k, cur));
    return Nearest(way, gap);
  }

  // The shortest displacement from `cur` that puts the proxy at least kSkinMm outside every
  // surface held (x . n_k >= -gap_k with the gaps of Admissible not clamped: negative where
  // the proxy overlaps); zero if there is none (the surfaces leave no room).
  Vec3 Separation(const Vec3& cur) const {
    std::array<double, kMaxPlanes> gap{};
    for (int k = 0; k < count_; ++k) gap[static_cast<std::size_t>(k)] = Gap(k, cur);
    return Nearest(Vec3::Zero(), gap);
  }

 private:
  struct Plane {
    Vec3 normal = Vec3::Zero();
    double level_mm = 0;
  };
  static constexpr int kMaxPlanes = 3;
  static constexpr double kSameNormal = 0.999;
  static constexpr double kFeasibleMm = 1e-12;

  // How far the proxy at `cur` may still move toward surface k, mm (< 0: it must move away).
  double Gap(int k, const Vec3& cur) const {
    const Plane& p = planes_[static_cast<std::size_t>(k)];
    return cur.dot(p.normal) - p.level_mm - kSkinMm;
  }

  // The nearest x to `way` with x . n_k >= -gap_k for every plane held: every set of active
  // constraints is tried and the nearest feasible point kept; zero if none is feasible.
  Vec3 Nearest(const Vec3& way, const std::array<double, kMaxPlanes>& gap) const {
    Vec3 best = Vec3::Zero();
    double best_d2 = std::numeric_limits<double>::infinity();
    for (int mask = 0; mask < (1 << count_); ++mask) {
      Vec3 x = way;
      if (!ProjectOnto(mask, gap, &x)) continue;
      bool feasible = true;
      for (int k = 0; k < count_ && feasible; ++k) {
        feasible = x.dot(planes_[static_cast<std::size_t>(k)].normal) >=
                   -gap[static_cast<std::size_t>(k)] - kFeasibleMm;
      }
      const double d2 = (x - way).squaredNorm();
      if (feasible && d2 < best_d2) {
        best = x;
        best_d2 = d2;
      }
    }
    return best;
  }

  // Moves *x to the nearest point with x . n_k = -gap_k for the planes selected by `mask`;
  // false if their normals are (nearly) linearly dependent.
  bool ProjectOnto(int mask, const std::array<double, kMaxPlanes>& gap, Vec3* x) const {
    using Cols = Eigen::Matrix<double, 3, Eigen::Dynamic, 0, 3, kMaxPlanes>;
    using Gram = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxPlanes, kMaxPlanes>;
    using Small = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kMaxPlanes, 1>;
    int cols = 0;
    for (int k = 0; k < count_; ++k) cols += (mask >> k) & 1;
    if (cols == 0) return true;
    Cols n(3, cols);
    Small g(cols);
    for (int k = 0, c = 0; k < count_; ++k) {
      if (((mask >> k) & 1) == 0) continue;
      n.col(c) = planes_[static_cast<std::size_t>(k)].normal;
      g(c++) = gap[static_cast<std::size_t>(k)];
    }
    const Gram gram = n.transpose() * n;
    const Eigen::LDLT<Gram> ldlt(gram);
    if (ldlt.info() != Eigen::Success || !(ldlt.vectorD().minCoeff() > 1e-6)) return false;
    const Small residual = n.transpose() * *x + g;
    *x -= n * ldlt.solve(residual);
    return true;
  }

  std::array<Plane, kMaxPlanes> planes_{};
  int count_ = 0;
};

// Pushes `pose` out of bone: first along the reported way out; if it still overlaps (a wedge
// between surfaces, e.g. a shaft between acromion and humeral head), by the shortest
// displacement that clears every surface met so far (ContactPlanes::Separation), at most
// kReachMm. False if it is still inside after kMaxPushes tries; `pose` is then unchanged.
// Without haptics.slide: every push along the reported way out, and a failed push-out leaves
// the pose where the pushes took it (the earlier proxy, bit for bit).
bool PushOut(const Model& model, const ToolState& tool, Pose* pose, collision::ToolBoneHit* hit,
             ProxyWorkspace* ws) {
  const bool slide = model.haptics.slide;
  const Pose start = *pose;
  ContactPlanes met;
  for (int k = 0; k < kMaxPushes && hit->clearance_mm < 0; ++k) {
    met.Add(pose->position_mm, hit->normal, hit->clearance_mm);
    Vec3 push = (kSkinMm - hit->clearance_mm) * hit->normal;
    if (slide && k > 0) {
      const Vec3 clear_all = met.Separation(pose->position_mm);
      if (clear_all.squaredNorm() > 0 && clear_all.norm() <= kReachMm) push = clear_all;
    }
    pose->position_mm += push;
    *hit = Clearance(model, tool, *pose, ws);
  }
  if (hit->clearance_mm >= 0) return true;
  if (slide) *pose = start;  // (the earlier proxy keeps the half-pushed pose)
  return false;
}

// Backs `pose` out along its shaft (tool -z), kRetreatStepMm at a time up to kMaxRetreatMm, to
// the first pose clear of bone by at least `min_clearance_mm` (ClearOfBone). False (pose
// unchanged) if none is.
bool Retreat(const Model& model, const ToolState& tool, double min_clearance_mm, Pose* pose,
             collision::ToolBoneHit* hit, ProxyWorkspace* ws) {
  const Vec3 back = -(pose->orientation * Vec3::UnitZ());
  for (int k = 1; k * kRetreatStepMm <= kMaxRetreatMm; ++k) {
    Pose p = *pose;
    p.position_mm += (k * kRetreatStepMm) * back;
    collision::ToolBoneHit h;
    if (ClearOfBone(model, tool, p, min_clearance_mm, &h, ws)) {
      *pose = p;
      *hit = h;
      return true;
    }
  }
  return false;
}

// Where the proxy heads from `cur` this iteration (a god-object's constrained step): the goal
// itself while the proxy is clear of bone (clearance >= kMinAdvanceMm) or has met no surface;
// else the goal with the part of the way into the surfaces met removed (ContactPlanes::
// Admissible), so the proxy slides along the bone toward the goal's nearest reachable point
// instead of zig-zagging into the bone and out again. The orientation is the goal's.
Pose SlideGoal(const Pose& cur, const Pose& goal, const collision::ToolBoneHit& hit,
               const ContactPlanes& planes) {
  if (hit.bone < 0 || hit.clearance_mm >= kMinAdvanceMm || planes.empty()) return goal;
  Pose slid = goal;
  slid.position_mm =
      cur.position_mm + planes.Admissible(cur.position_mm, goal.position_mm - cur.position_mm);
  return slid;
}

// What one iteration of Follow starts from.
struct IterationState {
  Pose cur;
  collision::ToolBoneHit hit;
  ContactPlanes planes;
  bool retreated = false;
};

bool SameBits(const IterationState& a, const IterationState& b) {
  return a.retreated == b.retreated && SameBits(a.cur, b.cur) && SameBits(a.hit, b.hit) &&
         a.planes.SameBits(b.planes);
}

// The first of seen[0 .. it) that equals seen[it] bit for bit; -1 if none.
int FirstSeen(const std::array<IterationState, kMaxIterations>& seen, int it) {
  for (int j = 0; j < it; ++j) {
    if (SameBits(seen[static_cast<std::size_t>(j)], seen[static_cast<std::size_t>(it)])) return j;
  }
  return -1;
}

// Follows the handle from `from` by conservative advancement: steps no longer than the current
// clearance (or kMinAdvanceMm near bone), each pushed out of bone if it overlaps. With
// haptics.slide (else the earlier proxy): a step that cannot be pushed out is retried shorter,
// kMaxHalvings times, and near bone each
// step heads for the goal slid along the surfaces met so far (SlideGoal). Stops at the handle (or
// its slid point), when stuck (no progress: the handle lies behind the surface), or after
// kMaxIterations.
Pose Follow(const Model& model, const ToolState& tool, const Pose& from, const Pose& goal,
            double arm, collision::ToolBoneHit* hit, int* iterations, ProxyWorkspace* ws) {
  const bool slide = model.haptics.slide;
  Pose cur = from;
  *hit = Clearance(model, tool, cur, ws);
  if (hit->clearance_mm < 0 && !PushOut(model, tool, &cur, hit, ws) &&
      !(slide && Retreat(model, tool, 0.0, &cur, hit, ws))) {
    return cur;
  }
  ContactPlanes planes;
  if (hit->bone >= 0 && hit->clearance_mm < kMinAdvanceMm) {
    planes.Add(cur.position_mm, hit->normal, hit->clearance_mm);
  }
  int it = 0;
  bool retreated = false;
  // The iteration is a function of (cur, *hit, planes, retreated) alone (the goal, the bones and
  // the instrument stay fixed during Follow). Once that state repeats, bit for bit, an earlier
  // one, the proxy is in a cycle that no exit test ended the first time round (a proxy wedged in
  // a carved hole alternating between its walls, pushed out of one into the other): it would run
  // to kMaxIterations, so the state it would end in is taken from the cycle instead of computed.
  std::array<IterationState, kMaxIterations> seen;
  for (; it < kMaxIterations; ++it) {
    seen[static_cast<std::size_t>(it)] = IterationState{cur, *hit, planes, retreated};
    const int first = ws->shortcuts ? FirstSeen(seen, it) : -1;
    if (first >= 0) {
      ++ws->cycles;
      const IterationState& end =
          seen[static_cast<std::size_t>(first + (kMaxIterations - first) % (it - first))];
      cur = end.cur;
      *hit = end.hit;
      it = kMaxIterations;
      break;
    }
    const Pose target = slide ? SlideGoal(cur, goal, *hit, planes) : goal;
    const double remaining = Motion(cur, target, arm);
    if (remaining <= kArrivedMm) break;
    // conservative advancement: a tool clear of bone by c moves c - kSkinMm safely (the earlier
    // proxy: c)
    const double skin = slide ? kSkinMm : 0.0;
    double advance = hit->clearance_mm >= kMinAdvanceMm ? hit->clearance_mm - skin : kMinAdvanceMm;
    Pose next;
    collision::ToolBoneHit h;
    bool placed = false;
    const int halvings = slide ? kMaxHalvings : 0;
    for (int halving = 0; halving <= halvings && !placed; ++halving, advance *= 0.5) {
      next = Interpolate(cur, target, std::min(1.0, advance / remaining));
      h = Clearance(model, tool, next, ws);
      const Vec3 met_at = next.position_mm;
      const collision::ToolBoneHit met = h;
      placed = h.clearance_mm >= 0 || PushOut(model, tool, &next, &h, ws);
      if (placed && met.clearance_mm < 0) planes.Add(met_at, met.normal, met.clearance_mm);
    }
    if (!placed) {
      // Stuck: every shorter step overlaps bone beyond the push-out. Pressing into bone (the
      // handle behind the surface) it stays; jammed in a cavity while the handle is clear of
      // bone and away, it backs out along its shaft (once per step) and follows from there.
      collision::ToolBoneHit at_goal;
      if (!slide || retreated || remaining <= kReachMm ||
          !ClearOfBone(model, tool, goal, 0.0, &at_goal, ws) ||
          !Retreat(model, tool, kJamRetreatClearanceMm, &cur, hit, ws)) {
        break;
      }
      retreated = true;
      planes = ContactPlanes();
      continue;
    }
    if (h.bone >= 0 && h.clearance_mm < kMinAdvanceMm) {
      planes.Add(next.position_mm, h.normal, h.clearance_mm);
    }
    const double progress = Motion(cur, next, arm);
    cur = next;
    *hit = h;
    if (progress <= kArrivedMm) break;
  }
  *iterations = it;
  return cur;
}

// Whether Follow would be given the same inputs as in `last` (its result is then last's): the
// same model and bone surfaces, instrument and jaw (its primitives and lever arm), start and goal.
bool SameInputs(const ProxyWorkspace::Resolution& last, const Model& model,
                std::uint64_t generation, const ToolState& tool, const Pose& from,
                const Pose& goal) {
  return last.model == &model && last.generation == generation &&
         last.instrument == tool.instrument && SameBits(last.jaw, tool.jaw) &&
         SameBits(last.from, from) && SameBits(last.goal, goal);
}

}  // namespace

void ResolveToolProxies(const Model& model, const std::array<ToolState, kToolSlots>& prev_tools,
                        State* state, ProxyWorkspace* ws) {
  ws->touches.clear();
  ws->iterations.fill(0);
  ws->clearance_queries = 0;
  ws->reused = 0;
  ws->cycles = 0;
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
    ProxyWorkspace::Resolution& last = ws->last[static_cast<std::size_t>(slot)];
    if (ws->shortcuts && SameInputs(last, model, ws->bones.generation, tool, from, goal)) {
      ++ws->reused;
      tool.pose = last.pose;
      hit = last.hit;
      ws->iterations[static_cast<std::size_t>(slot)] = last.iterations;
    } else {
      tool.pose = Follow(model, tool, from, goal, arm, &hit, &ws->iterations[slot], ws);
      last = ProxyWorkspace::Resolution{&model,
                                        ws->bones.generation,
                                        tool.instrument,
                                        tool.jaw,
                                        from,
                                        goal,
                                        tool.pose,
                                        hit,
                                        ws->iterations[static_cast<std::size_t>(slot)]};
    }
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
