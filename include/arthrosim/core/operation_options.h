#pragma once
// Thresholds of the instruments' operations: the scenario's optional `operations:` section
// (docs/scenario-format.md, docs/operations.md), part of the immutable Model. Lengths in mm,
// times in s, as the paper's thresholds read in centimetres (0.2 -> 2 mm).
#include <cstdint>
#include <string>
#include <vector>

namespace arthrosim {

/// How the scissors cut (scenario `operations.scissors.mode`).
enum class CutMode : std::uint8_t {
  kRemove,  ///< delete the tets the blade triangle crosses (the paper's real-time mode)
  kSplit,   ///< split them along the blade plane (new nodes; volume conserved)
};

/// Scissors (scenario `operations.scissors`; docs/operations.md).
struct ScissorsOptions {
  CutMode mode = CutMode::kRemove;
  /// Split mode: a cut passing within this fraction of an edge's length of one of its ends
  /// snaps to that node (the cut passes through the node: no sliver elements), in [0, 0.5).
  /// 0.2 keeps every piece's radius ratio >= 0.03 on grids of Kuhn tets (docs/operations.md).
  double snap_fraction = 0.2;
  /// Smallest jaw increase per step that counts as closing (0 open ... 1 closed).
  double min_jaw_step = 1e-6;
};

/// Cutter (scenario `operations.cutter`).
struct CutterOptions {
  /// A thread segment within this distance (mm) of the triangle between the blades is "between
  /// the blades" (blade half-thickness + thread radius + slack).
  double reach_mm = 1.0;
  /// The blades meet (and cut) on the step the jaw closes past this value (0 open ... 1 closed):
  /// one cut per closing stroke.
  double cut_at_jaw = 0.9;
};

/// Shaver and electrocautery (scenario `operations.shaver`, `operations.electrocautery`).
struct SoftShavingOptions {
  double rate_mm_s = 2.0;  ///< depth removed per second of contact at a touched vertex, mm/s
  double reach_mm = 0.5;   ///< surface vertices this close (mm) to the tip are touched
  double smoothing = 0.5;  ///< share (0..1) of the mean inward move passed to ring neighbours
  double min_volume_fraction = 0.2;  ///< a tet below this share of its initial rest volume goes
};

/// Burr (scenario `operations.burr`): bone removal while button 1 is held in contact.
struct BurrOptions {
  double depth_rate_mm_s = 1.0;    ///< surface recession speed at full speed on hardness 1, mm/s
  double speed = 1.0;              ///< burr speed as a fraction of full speed, (0, 1]
  double max_edge_mm = 0.5;        ///< bone edges near the burr are split down to this, mm
  double smoothing_ring_mm = 0.5;  ///< width of the crater rim that is smoothed, mm
};

/// Awl (scenario `operations.awl`): the pilot hole.
struct AwlOptions {
  int method = 2;             ///< 1: contact vertex + neighbours; 2: axis-aligned hole
  double max_angle_deg = 60;  ///< method 2: tool axis vs tip->contact direction, deg
  double max_edge_mm = 0.25;  ///< bone edges near the point are split down to this, mm
  double min_depth_mm = 0.2;  ///< a hole is recorded once it is this deep, mm
};

/// Anchor (scenario `operations.anchor`): seated with button 2 of the awl in a hole.
struct AnchorOptions {
  double min_hole_depth_mm = 3.0;      ///< a hole must be at least this deep, mm
  double capture_radius_mm = 3.0;      ///< awl tip within this of a hole's axis seats it, mm
  double stiffness_n_per_mm = 2000.0;  ///< suture limb to anchor spring, N/mm
  std::vector<std::string> sutures;    ///< threads whose node 0 the anchor carries
};

/// Grasper (tissue) and retriever (thread), Choi et al. 2020 section III.4: while the jaw is
/// closed a spring holds the grasped point at the place in the tool frame where it was taken.
struct GraspOptions {
  double dist_limit_mm = 2.0;       ///< Dist_Limit: grasp reach, and the stretch that releases
  double jaw_closed = 0.8;          ///< jaw value (0 open .. 1 closed) from which it grasps
  double stiffness_n_per_mm = 5.0;  ///< grasp spring, N/mm
};

/// Scorpion needle, Choi et al. 2020 section III.5 (two buttons).
struct ScorpionNeedleOptions {
  double dist_limit_1_mm = 5.0;  ///< Dist_limit_1: reach to the thread node it ties to the tool
  double dist_limit_2_mm = 2.0;  ///< Dist_limit_2: tissue grasp reach and releasing stretch
  /// Jaw value (0 open .. 1 closed) from which button 1 holds tissue: the jaws close on the
  /// tissue between them, so jaws slid open around a tendon do not take it on the way in.
  double grasp_jaw = 0.35;
  double node_spacing_mm = 1.0;  ///< spacing of the thread nodes laid out of the exit point
  int nodes_through = 3;         ///< the node this many further sits at the exit (upper) point
  double tissue_stiffness_n_per_mm = 5.0;  ///< tool-tissue grasp spring, N/mm
  double thread_stiffness_n_per_mm = 5.0;  ///< tool-thread spring, N/mm
  double stitch_stiffness_n_per_mm = 5.0;  ///< thread-tissue stitch springs, N/mm
  /// Friction each stitch spring opposes to the thread sliding through the bite, N (the stitch
  /// ends slide along the thread); < 0: the stitches hold fixed thread nodes (the paper).
  double stitch_friction_n = 0.5;
};

/// Hook (contact only; scenario `operations.hook`): a thread in the bend of the barb is snagged
/// by a frictionless sliding spring at the bend, so the hook pulls it along while the thread runs
/// through the bend; released when the hook is turned away or the thread slips out.
struct HookOptions {
  double catch_reach_mm = 1.5;      ///< a thread this close (mm) to the bend point is snagged
  double dist_limit_mm = 3.0;       ///< the thread slips out beyond this stretch, mm
  double release_angle_deg = 100;   ///< turned away: bend opening vs pull beyond this, deg
  double stiffness_n_per_mm = 5.0;  ///< bend-thread spring, N/mm
  double friction_n = 0.0;          ///< friction of the thread running through the bend, N
};

/// Knot pusher, Choi et al. 2020 section III.6 (two buttons), plus the knot security pull test
/// (docs/operations.md "Knot tying").
struct KnotPusherOptions {
  double dist_limit_mm = 2.0;              ///< Dist_limit: reach to the thread node it attaches
  double thread_stiffness_n_per_mm = 5.0;  ///< tool-thread spring, N/mm
  double knot_stiffness_n_per_mm = 20.0;   ///< each spring binding the two limbs in the knot, N/mm
  double knot_size_mm = 1.2;               ///< scale of the laid half hitch (trefoil), mm
  int target_node = 9;         ///< the knot seats this many nodes out from the tissue side
  double pull_force_n = 5.0;   ///< security test: load on each limb, N
  double pull_time_s = 0.5;    ///< security test: how long the load is held, s
  double slip_limit_mm = 3.0;  ///< security test: slip beyond this is a failed knot, mm
};

/// Thresholds of the instrument operations (scenario section `operations:`; defaults documented
/// in docs/operations.md, in mm and s). One sub-struct per operation.
struct OperationOptions {
  ScissorsOptions scissors;
  CutterOptions cutter;
  SoftShavingOptions shaver;
  SoftShavingOptions electrocautery{1.0, 0.3, 0.5, 0.2};
  BurrOptions burr;
  AwlOptions awl;
  AnchorOptions anchor;
  GraspOptions grasper;
  GraspOptions retriever;
  ScorpionNeedleOptions scorpion_needle;
  KnotPusherOptions knot_pusher;
  HookOptions hook;
};

}  // namespace arthrosim
