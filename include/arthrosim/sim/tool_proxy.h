#pragma once
// The tool proxy (god-object: Zilles & Salisbury 1995; Ruspini et al. 1997). The commanded pose
// of a slot is its handle (State ToolState::handle_pose); the simulated instrument (ToolState::
// pose) is a proxy that follows the handle along the swept path but stays outside rigid bone and
// slides along its surface. The force fed back to the hand is a virtual coupling spring-damper
// between handle and proxy plus the soft-tissue reactions on the instrument, clamped to
// Model::haptics.max_force_n.
#include <array>
#include <cstdint>
#include <vector>

#include "arthrosim/collision/contact_generation.h"
#include "arthrosim/collision/tool_bone_query.h"
#include "arthrosim/core/model.h"
#include "arthrosim/core/state.h"

namespace arthrosim::sim {

/// Most resolution iterations of one slot in one step (then the proxy stays where it got).
constexpr int kProxyMaxIterations = 96;

/// Derived data and work lists of the proxy stage (Workspace: rebuilt from State at will).
struct ProxyWorkspace {
  collision::BoneQueryWorld bones;
  std::vector<collision::ToolPrimitive> primitives;
  /// (slot, bone) pairs the proxies rest against this step, with the bone contact point.
  std::vector<ToolContact> touches;
  std::array<int, kToolSlots> iterations{0, 0};  ///< resolution iterations used (diagnostics)
  int clearance_queries = 0;  ///< tool-bone clearance searches this step, all slots (diagnostics)
  /// Each slot's last resolution: its inputs (model, bone surfaces by generation, instrument,
  /// jaw, start and goal poses, bit for bit) and its result. A step with the same inputs (a hand
  /// held still against bone) takes the result instead of resolving again: the resolution is a
  /// function of these inputs alone.
  struct Resolution {
    const Model* model = nullptr;
    std::uint64_t generation = 0;
    int instrument = -1;
    double jaw = 0;
    Pose from;
    Pose goal;
    Pose pose;
    collision::ToolBoneHit hit;
    int iterations = 0;
  };
  std::array<Resolution, kToolSlots> last;
  /// False: every slot-step resolved in full, without the two shortcuts (a step's inputs equal
  /// to the last step's; a cycle of iteration states), which give the same bits (tests compare).
  bool shortcuts = true;
  int reused = 0;  ///< slot-steps this step that took the last resolution (diagnostics)
  int cycles = 0;  ///< slot-steps this step ended by a repeated iteration state (diagnostics)
};

/// Moves each inserted slot's proxy (tools[s].pose) from its last pose toward tools[s].
/// handle_pose, stopping at and sliding along bone surfaces, and lists the bone touches. Near
/// bone the proxy heads for the handle with the part of the way into the bone surfaces it met
/// this step removed (at most three surfaces: a face, a crease, a corner; a small quadratic
/// program), so it reaches the handle's nearest reachable point in a few iterations; it stops in
/// a corner the handle lies behind. At most kProxyMaxIterations iterations per slot. A
/// newly inserted instrument starts at its handle if that pose is clear of bone, else at its
/// portal. Within 6 mm of bone, against soft tissue it pressed toward the bone last step
/// (reaction > 0.05 N), the proxy advances at most 0.5 mm per step along the push, and not at all
/// once the reaction reaches haptics.max_force_n, so tissue trapped against bone is pressed, not
/// crushed through. With
/// model.haptics.proxy false the proxy is the handle. Deterministic.
void ResolveToolProxies(const Model& model, const std::array<ToolState, kToolSlots>& prev_tools,
                        State* state, ProxyWorkspace* ws);

/// The virtual coupling force on the hand of one slot, N: stiffness * (proxy - handle) plus
/// damping * d/dt(proxy - handle) (from the previous step's poses when the same instrument was
/// held). Zero if nothing is inserted. Not clamped.
Vec3 CouplingForce(const Model& model, const ToolState& prev, const ToolState& now);

/// Force magnitude clamp of the haptic feedback: f scaled down to max_force_n if longer.
Vec3 ClampForce(const Vec3& f, double max_force_n);

}  // namespace arthrosim::sim
