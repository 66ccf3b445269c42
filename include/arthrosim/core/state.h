#pragma once
// The mutable State: the minimum needed to resume a run bit for bit. Everything derived from
// (Model, State) — element rotations, assembled matrices, BVH trees — lives in the sim
// Workspace and is rebuilt on restore. Rendering, scoring and output only read State.
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "arthrosim/core/mesh_types.h"
#include "arthrosim/core/types.h"

namespace arthrosim {

/// Deformable body state. Node arrays may grow (tet splitting appends nodes).
struct SoftBodyState {
  Points x;                     ///< 3 x N positions, mm
  Points v;                     ///< 3 x N velocities, mm/s
  Points x_rest;                ///< 3 x N rest positions, mm (shaving re-rests them)
  std::vector<mesh::Tet> tets;  ///< element connectivity; initial tets first, splits appended
  std::vector<std::uint8_t> tet_alive;  ///< 1 = element present, 0 = removed (cut/shaved)
  Points dv_warm;                       ///< 3 x N last velocity increment, CG warm start
  /// The mesh and positions the soft-tissue CG preconditioner in use was factored from (set by
  /// the solver; kept here so a restored run rebuilds the same preconditioner and continues bit
  /// for bit; docs/contact-model.md "Deferred refactorisation"):
  /// x_factor: 3 x M anchor positions (mm); empty = factor_rest, missing columns = their rest.
  Points x_factor;
  /// 3 x M rest positions of the factored mesh (its M nodes); empty = x_rest.
  Points factor_rest;
  /// Alive flags of the factored mesh's tets (tets past its end are not in it); empty =
  /// tet_alive.
  std::vector<std::uint8_t> factor_alive;
  /// The same three for the factor being prepared, which replaces them at
  /// State::factor_switch_step (meaningful only while that is >= 0: at the switch the two sets
  /// are swapped, so these then hold the previous factor's, kept for their storage).
  Points x_factor_next;
  Points factor_rest_next;
  std::vector<std::uint8_t> factor_alive_next;
  /// Rest volume taken away by cutting and shaving so far, mm^3 (sum of removed tets' rest
  /// volumes plus the rest volume shaved off surviving tets).
  double removed_volume_mm3 = 0;
  /// Per node: 1 = surface marked by the electrocautery. Empty or shorter than the node count
  /// (nodes appended later) means 0 for the missing nodes.
  std::vector<std::uint8_t> cauterized;
};

/// Bone surface state (reshaped by burr and awl).
struct BoneState {
  mesh::TriMesh surface;          ///< current closed surface, mm
  double removed_volume_mm3 = 0;  ///< initial enclosed volume minus current, mm^3
  /// Removed volume booked per Model::regions entry (a carve counts for every region of this
  /// bone whose box holds its contact centre), plus one last entry for removal in none, mm^3.
  std::vector<double> removed_by_region_mm3;
  /// Goes up with every change of `surface` (code that edits it must increment it), so
  /// observers (collision trees) compare a number instead of the whole surface each step.
  std::uint64_t revision = 0;
};

/// Suture thread state.
struct ThreadState {
  Points x;                              ///< 3 x N positions, mm
  Points v;                              ///< 3 x N velocities, mm/s
  std::vector<std::uint8_t> node_alive;  ///< 0 once cut away by the cutter
};

/// Where one end of a spring constraint sits. A point is a weighted sum of up to four nodes of
/// one body (tet barycentric, triangle barycentric with one zero weight, a single node with
/// weight 1), or a point fixed in a tool frame or in the world.
struct ConstraintEnd {
  enum class Kind : std::uint8_t { kWorld, kSoftBody, kThread, kBone, kTool };
  Kind kind = Kind::kWorld;
  std::int32_t index = -1;  ///< body / thread / bone / tool-slot index
  std::array<std::int32_t, 4> nodes{-1, -1, -1, -1};
  std::array<double, 4> weights{0, 0, 0, 0};
  Vec3 offset_mm = Vec3::Zero();  ///< world point (kWorld, kBone) or tool-frame point (kTool)
};

/// A runtime zero-or-positive-rest-length spring between two points: grasps, suture stitches,
/// knots, anchors. Created and removed by instruments at any step.
struct SpringConstraint {
  std::int64_t id = 0;  ///< unique, increasing in creation order
  std::string tag;      ///< "grasp", "suture", "knot", "anchor", ...
  ConstraintEnd a, b;
  double stiffness_n_per_mm = 1.0;  ///< N/mm
  double rest_length_mm = 0.0;
  /// Sliding end (physics::SlideConstraintEnds): >= 0, the thread end (a if both are threads)
  /// is a point along its thread (nodes i, i+1 with weights 1-f, f) that moves along the chain
  /// when the spring's pull along the thread exceeds this friction force, N; < 0, fixed ends.
  double slide_friction_n = -1.0;
};

/// Per instrument-slot state (a working hand / portal).
struct ToolState {
  std::int32_t instrument = -1;  ///< index into Model::instruments, -1 = none inserted
  Pose pose;                 ///< instrument (proxy) tip pose in world (+z forward; shaft along -z)
  Pose handle_pose;          ///< commanded (device / script) tip pose; pose follows it outside bone
  double jaw = 0;            ///< 0 open ... 1 closed
  std::uint8_t buttons = 0;  ///< bit 0 = button 1, bit 1 = button 2
  /// Force fed back to the hand this step, N: handle-proxy coupling plus soft-tissue reactions,
  /// clamped to Model::haptics.max_force_n.
  Vec3 force_n = Vec3::Zero();
  /// Reactions of soft tissue, threads and held springs on the instrument this step, N
  /// (unclamped; force_n without the coupling). The proxy reads it to bound pressing on tissue.
  Vec3 tissue_force_n = Vec3::Zero();
};

/// Arthroscope state.
struct CameraState {
  Pose pose;                 ///< scope tip pose (+z forward along the shaft; see CameraModel)
  double lens_roll_rad = 0;  ///< light-post rotation about the shaft (sweeps the 30 deg view)
  double head_roll_rad = 0;  ///< camera-head rotation (image up)
};

/// A discrete happening, written to /events.
struct Event {
  std::int64_t step = 0;
  double time_s = 0;
  std::string kind;  ///< contact_start, contact_end, cut, grasp, release, hole, ...
  std::string tool;
  std::string body;
  std::string detail;
  Vec3 position_mm = Vec3::Zero();
};

/// A (tool slot, body) pair in contact at the end of a step. The collision stage compares
/// consecutive steps to emit contact_start / contact_end events, so it belongs to State.
struct ToolContact {
  std::int32_t tool_slot = -1;
  ConstraintEnd::Kind body_kind = ConstraintEnd::Kind::kSoftBody;  ///< kSoftBody, kThread, kBone
  std::int32_t body = -1;                                          ///< body index in the Model
  Vec3 position_mm = Vec3::Zero();  ///< contact point (force-weighted mean), mm
};

/// A pilot hole made by the awl in a bone (awl_drill.cpp).
struct BoneHole {
  std::int32_t bone = -1;        ///< bone index in the Model
  std::int32_t tool_slot = -1;   ///< slot of the awl that made it
  Vec3 entry_mm = Vec3::Zero();  ///< where the hole axis crosses the original surface, mm
  Vec3 axis = Vec3::UnitZ();     ///< unit, into the bone
  double depth_mm = 0;           ///< deepest point below the entry along the axis, mm
  double diameter_mm = 0;        ///< at the entry, mm
  double angle_deg = 0;          ///< between the axis and the bone surface (90 = perpendicular)
  std::uint8_t open = 0;         ///< 1 while the awl is still in it (the hole can deepen)
};

/// A suture anchor seated in a hole (anchor.cpp): a rigid body fixed to the bone.
struct AnchorState {
  std::int32_t bone = -1;
  std::int32_t hole = -1;           ///< index into State::holes
  Vec3 position_mm = Vec3::Zero();  ///< eyelet at the bottom of the hole, mm
  Vec3 axis = Vec3::UnitZ();        ///< insertion direction, unit
  double depth_mm = 0;              ///< below the cortex (the hole's entry), mm
  double angle_deg = 0;             ///< insertion angle to the bone surface, deg
};

inline constexpr int kToolSlots = 2;

/// Controller state of a synthetic script's force push on one tool slot (input::ScriptSource):
/// the push integrates the force fed back after every step, so its future frames depend on this
/// history. Kept in State (set by the run loop after each input frame) so that a run restored
/// from a checkpoint continues it bit for bit.
struct ScriptPushState {
  std::int32_t action = -1;  ///< index of the push in the slot's actions; -1 = none yet
  double depth_mm = 0;       ///< advance along the tool axis past the push's nominal start, mm
  double t_prev_s = 0;       ///< time of the last integration, s
};

struct State {
  std::int64_t step = 0;
  double time_s = 0;
  std::vector<SoftBodyState> soft_bodies;  ///< parallel to Model::soft_bodies
  std::vector<BoneState> bones;            ///< parallel to Model::bones
  std::vector<ThreadState> threads;        ///< parallel to Model::threads
  std::array<ToolState, kToolSlots> tools;
  CameraState camera;
  std::vector<SpringConstraint> constraints;  ///< sorted by id
  std::int64_t next_constraint_id = 1;
  std::uint64_t rng_state = 0;             ///< splitmix64 state, seeded from Model::options.seed
  std::vector<Event> events;               ///< events of the last step only
  std::vector<ToolContact> tool_contacts;  ///< touching (tool, body) pairs, sorted (collision)
  std::vector<BoneHole> holes;             ///< pilot holes, in creation order
  std::vector<AnchorState> anchors;        ///< seated anchors, in creation order
  /// Force-push controllers of the input script, one per slot (default when the input is not a
  /// script): input state that a checkpoint must carry, not simulation state.
  std::array<ScriptPushState, kToolSlots> script_push{};
  /// Step at whose start the soft-tissue preconditioner being prepared (SoftBodyState::
  /// x_factor_next ...) replaces the one in use; -1 when none is being prepared.
  std::int64_t factor_switch_step = -1;
  /// CG iterations of the first solve made with the soft-tissue preconditioner factor in use
  /// (SolverOptions::refactor_slack_iterations); -1 before any.
  std::int32_t factor_baseline_cg = -1;
};

struct Model;
/// The state at t = 0: rest configuration, nothing inserted, camera at its initial pose.
State MakeInitialState(const Model& model);

/// Bit-for-bit equality of two states (every field). Used by determinism and restore tests.
bool BitwiseEqual(const State& a, const State& b);

/// 64-bit FNV-1a hash over every field of the state, for golden determinism checks.
std::uint64_t HashState(const State& s);

}  // namespace arthrosim
