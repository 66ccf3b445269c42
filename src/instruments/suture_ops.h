#pragma once
// Grasping and suturing operations (grasper, retriever, scorpion needle) and the geometric
// queries they share: the nearest tissue surface point through the collision trees, the nearest
// thread node, the tool-held springs of a slot.
#include <array>
#include <cstdint>
#include <vector>

#include "arthrosim/instruments/instruments.h"

namespace arthrosim::instruments {

/// Grasper (muscle, tendon; Choi et al. 2020 section III.4). With the jaw closed
/// (jaw >= operations.grasper.jaw_closed) while the tool touches a soft body, a spring (tag
/// "grasp") joins the nearest surface point of that body within dist_limit of the closed jaw to
/// the place in the tool frame where that point was; it is removed when the jaw opens or the
/// spring stretches beyond dist_limit. Events `grasp` and `release`.
void GrasperOperation(const Model& model, int slot, const StepContext& context, State* state,
                      InstrumentScratch* scratch);

/// Retriever (thread): the same on the nearest live thread node within dist_limit of the closed
/// jaw (options operations.retriever).
void RetrieverOperation(const Model& model, int slot, const StepContext& context, State* state,
                        InstrumentScratch* scratch);

/// Scorpion needle (section III.5): button 1 grasps tissue between the jaws (tag
/// "scorpion_tissue", released beyond dist_limit_2 or when button 1 is let go) and ties the
/// nearest thread node within dist_limit_1 to the tool (tag "scorpion_thread", event
/// `thread_catch`); button 2 with both held and the tool touching that tissue passes the thread
/// through it along the paper's penetration path and stitches it (tag "stitch", event
/// `suture_pass` with the bite).
void ScorpionNeedleOperation(const Model& model, int slot, const StepContext& context, State* state,
                             InstrumentScratch* scratch);

/// Hook (contact only): a live thread within operations.hook.catch_reach of the bend's seat
/// while the hook is drawn toward its mouth is snagged by a sliding spring (tag "hook", event
/// `hook_catch`) that pulls it along as it runs through the bend; released (event
/// `hook_release`) when the pull points more than release_angle away from into the bend (the
/// hook turned away) or stretches beyond dist_limit.
void HookOperation(const Model& model, int slot, const StepContext& context, State* state,
                   InstrumentScratch* scratch);

/// Knot pusher (section III.6; knot_pusher.cpp): button 1 ties the nearest thread node within
/// dist_limit to the tool (tag "knot_pusher", event `thread_catch`, two threads at most); when
/// the second is held it throws a half hitch in the limbs and, if IdentifyKnot finds a real knot,
/// binds them with "knot" springs (event `knot`). Button 2 slides the knot toward the target node
/// as the loop slackens; there the tool lets go and the pull test runs (event `knot_seated`).
void KnotPusherOperation(const Model& model, int slot, const StepContext& context, State* state,
                         InstrumentScratch* scratch);

/// A point on a soft body's boundary surface: triangle (global node ids) and barycentric
/// weights, in the current state.
struct SurfacePoint {
  std::int32_t body = -1;  ///< soft body index, -1 = none found
  std::int32_t tri = -1;   ///< triangle index in the body's collision surface
  std::array<std::int32_t, 3> nodes{-1, -1, -1};
  std::array<double, 3> weights{0, 0, 0};
  Vec3 point_mm = Vec3::Zero();
  double distance_mm = 0;
};

/// Slack (mm) added to tree queries: the trees hold the positions of this step's detection, the
/// state those after the solve, which differ by one step's motion.
inline constexpr double kTreeSlackMm = 1.0;

/// Nearest point of soft body `body`'s surface to the segment (a, b) within `reach` mm, found
/// through the body's triangle tree (candidates from the tree, distances with the state's
/// current positions; ties to the lower triangle index). body = -1 in the result if none.
SurfacePoint NearestSurfacePoint(const State& state, const collision::CollisionWorld& world,
                                 int body, const Vec3& a, const Vec3& b, double reach);

/// Soft bodies that tool `slot` touches in this step's solved contacts (force > 0), ascending.
std::vector<std::int32_t> TouchedSoftBodies(const StepContext& context, int slot);

/// The constraint of tool slot `slot` with this tag (end a on the tool), or -1.
std::int64_t ToolConstraint(const State& state, int slot, const char* tag);

/// A spring from tool slot `slot` (end a, at the tool-frame position of `world_point_mm` in the
/// current pose) to `other` (end b), rest length 0; returns its id.
std::int64_t AddToolSpring(State* state, int slot, const Vec3& world_point_mm,
                           const ConstraintEnd& other, double stiffness_n_per_mm, const char* tag);

/// A thread node caught by a tool: which, and how far from the point it was sought from.
struct CaughtNode {
  int thread = -1;  ///< -1: none within reach
  int node = -1;
  double distance_mm = 0;
  std::int64_t constraint = -1;  ///< the tool spring made
};

/// Ties to tool slot `slot` (a `tag` spring of `stiffness_n_per_mm`, rest length 0) the live,
/// not fixed thread node nearest `point_mm` within `reach_mm`, skipping threads for which
/// `skip_thread[t]` is true (empty: none skipped); ties go to the lower thread, then node index.
/// Returns thread = -1 and makes nothing when no node is within reach.
CaughtNode CatchNearestThreadNode(const Model& model, int slot, const Vec3& point_mm,
                                  double reach_mm, const std::vector<bool>& skip_thread,
                                  double stiffness_n_per_mm, const char* tag, State* state);

/// Current length of a constraint (distance between its two ends), mm.
double ConstraintStretchMm(const State& state, std::int64_t id);

/// The closed jaw's centre line in world coordinates (hinge to tip: tool frame (0, 0, -L) to
/// the origin), mm.
void JawSegment(const Model& model, const ToolState& tool, Vec3* hinge, Vec3* tip);

/// "x,y,z" with 3 decimals, for event details.
std::string FormatPoint(const Vec3& p);

}  // namespace arthrosim::instruments
