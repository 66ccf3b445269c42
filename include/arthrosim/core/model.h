#pragma once
// The immutable Model: everything loaded from a scenario. Built once by io::LoadScenario, then
// only read. What a step changes lives in State (state.h). Units: mm, s, kg internally; the
// material fields below keep the scenario's units (Pa, kg/m^3) and physics converts them with
// units.h, so a Model prints back exactly what the user wrote.
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "arthrosim/core/mesh_types.h"
#include "arthrosim/core/operation_options.h"
#include "arthrosim/core/types.h"

namespace arthrosim {

/// Isotropic linear-elastic material with Rayleigh damping.
struct Material {
  std::string name;
  double young_modulus_pa = 0;    ///< E, Pa (> 0)
  double poisson_ratio = 0;       ///< nu, in [0, 0.5)
  double density_kg_m3 = 0;       ///< rho, kg/m^3 (> 0)
  double rayleigh_mass = 0;       ///< alpha, 1/s: damping force = -alpha * M v
  double rayleigh_stiffness = 0;  ///< beta, s: damping force = -beta * K v
};

/// Volumetric deformable body (muscle, tendon, biceps).
struct SoftBodyModel {
  std::string name;
  std::string mesh_file;    ///< as written in the scenario (relative to it)
  mesh::TetMesh rest_mesh;  ///< initial mesh, mm, positively oriented tets
  Material material;
  std::vector<std::int32_t> fixed_nodes;  ///< sorted, unique node indices held in place
};

/// Rigid bone surface (humerus, acromion). Fixed in space; burr and awl reshape it.
struct BoneModel {
  std::string name;
  std::string mesh_file;
  mesh::TriMesh surface;  ///< closed, outward oriented, mm
  double hardness = 1.0;  ///< dimensionless removal-rate divisor for burr/awl (1 = cancellous)
  /// Surface groups of the mesh that are a tissue of their own (scenario `tissues`, e.g.
  /// "cartilage", "labrum"): drawn with their own material and tissue id, burring them is
  /// collateral damage (docs/operations.md, Bone). At most 127.
  std::vector<std::string> tissues;
  /// Per triangle of `surface`: index into `tissues`, or -1 for the bone itself; empty when
  /// `tissues` is.
  std::vector<std::int8_t> tri_tissue;
};

/// Suture thread: a chain of nodes (mass-spring), No. 2 FiberWire by default.
struct ThreadModel {
  std::string name;
  mesh::LineMesh initial;             ///< initial node positions and segments (a chain 0-1-...-n)
  double diameter_mm = 0.55;          ///< USP 2
  double density_kg_m3 = 1300;        ///< UHMWPE core (970) + polyester jacket (1380)
  double stretch_stiffness_n = 5000;  ///< EA, N: ~250 N break over ~5 % strain (Turker 2011)
  double bend_stiffness_n_mm2 = 0;    ///< EI, N*mm^2 (0 disables bending)
  double damping_per_s = 0;           ///< mass-proportional damping, 1/s
  double max_speed_mm_s = 500;        ///< anti-jitter node speed cap (paper section II)
  bool self_collision = true;
  std::vector<std::int32_t> fixed_nodes;  ///< e.g. node 0 held by an anchor in bone
};

/// The instruments of the paper's Table 1, plus the hook.
enum class InstrumentKind : std::uint8_t {
  kScissors,
  kCutter,
  kBurr,
  kShaver,
  kElectrocautery,
  kAwl,
  kRetriever,
  kGrasper,
  kScorpionNeedle,
  kKnotPusher,
  kHook,
};
inline constexpr int kInstrumentKindCount = 11;

/// One instrument available in the scenario. Tool frame convention (shared by instruments and
/// the arthroscope): origin at the tip, +z points forward (handle -> tip), so the shaft runs
/// from the tip back along -z to the handle; jaws open in the x-z plane.
struct InstrumentModel {
  std::string name;  ///< unique, used in trajectories and HDF5 (/tools/<name>)
  InstrumentKind kind{};
  std::string portal;  ///< name of the portal it enters through
  double shaft_diameter_mm = 4.5;
  double shaft_length_mm = 150;
  double tip_length_mm = 8;  ///< working part: blade/jaw length, burr/awl tip length
  double tip_radius_mm = 2;  ///< burr sphere radius, awl radius, shaver window half-width
};

/// Skin entry point for instruments and scope.
struct Portal {
  std::string name;
  Vec3 position_mm = Vec3::Zero();
};

/// Arthroscope optics: 4 mm, 30-degree scope, 105-degree field of view (Kwak et al. 2019).
struct CameraModel {
  std::string portal = "posterior";
  double fov_deg = 105;        ///< image-circle field of view (in fluid)
  double lens_angle_deg = 30;  ///< direction of view from the shaft axis
  double diameter_mm = 4.0;
  double near_mm = 1.0;
  double far_mm = 100.0;
  Pose initial_pose;  ///< scope tip pose; shaft axis +z forward, +y image up at zero
                      ///< rolls; the view direction is +z tilted lens_angle toward +y
};

/// A named point for plans, scripts and scoring (e.g. footprint centre, anchor site).
struct Landmark {
  std::string name;
  std::string body;  ///< body it lies on ("" = world)
  Vec3 position_mm = Vec3::Zero();
};

/// A named region of a body: the nodes (soft/thread) or surface vertices (bone) inside a shape.
struct Region {
  std::string name;
  std::string body;
  std::vector<std::int32_t> nodes;  ///< sorted node indices of that body inside the region
  Vec3 box_min_mm = Vec3::Zero();   ///< the shape as written: an axis-aligned box...
  Vec3 box_max_mm = Vec3::Zero();
};

/// Two soft bodies that share coincident nodes (muscle-tendon junction): physics merges them.
struct Join {
  std::string body_a, body_b;
  double tolerance_mm = 1e-6;
};

// ---- Solver, contact and thread-solver options: every numerical setting of the physics and
// collision stages, in one place with defaults and units (as MuJoCo keeps mjOption in
// mjModel). Each is a scenario key (sections `solver:`, `contact:`, `thread_solver:`,
// docs/scenario-format.md); the stages read them from here.

/// Soft-tissue time integrator.
enum class Integrator : std::uint8_t { kImplicitEuler, kArkode };

/// How the soft solver's CG applies the system matrix.
enum class SystemProduct : std::uint8_t {
  kAssembled,   ///< 3x3 block-sparse matrix assembled once per step (default, faster)
  kMatrixFree,  ///< element-by-element product R K_e R^T at every CG iteration
};

/// The soft solver's CG preconditioner.
enum class Preconditioner : std::uint8_t {
  kBlockJacobi,   ///< inverse 3x3 diagonal blocks of the current system matrix
  kRestCholesky,  ///< "warped" anchored factorisation: P^-1 = W Ka^-1 W^T with Ka the sparse
                  ///< LDLT of the system with the element rotations of the anchor positions
                  ///< SoftBodyState::x_factor (the rest positions while it is empty), and
                  ///< W per-node rotations taking the anchor's node rotations to the current
                  ///< ones (node rotation: polar of the sum of the incident element rotations).
                  ///< A step whose CG needs more than SolverOptions::refactor_iterations requests
                  ///< a new factor of the mesh and positions at its end, used refactor_lag_steps
                  ///< steps later (topology edits meanwhile: removed nodes drop out, new nodes
                  ///< get their block-Jacobi inverse); the factor's mesh and anchor are kept in
                  ///< State, so a restored run rebuilds the same factors
};

/// Soft-tissue solver options (scenario section `solver:`): implicit Euler + CG as SOFA's
/// EulerImplicitSolver + CGLinearSolver.
struct SolverOptions {
  Integrator integrator = Integrator::kImplicitEuler;
  int cg_max_iterations = 100;  ///< per solve, >= 1
  double cg_tolerance = 1e-8;   ///< relative residual |r|/|b|, > 0
  SystemProduct product = SystemProduct::kAssembled;
  Preconditioner preconditioner = Preconditioner::kRestCholesky;
  /// A step needing more CG iterations than this moves the factor anchor (0 = never: the
  /// preconditioner stays the warped rest factor). 10: with the ~5 ms refactorisation, the
  /// driven benchmark gives median 2.6 / mean 3.3 ms per step (12: 2.9 / 3.2; 8: 2.5 / 3.8).
  int refactor_iterations = 10;
  /// Deferred refactorisation: a new factor requested at step n (the step that needed more
  /// than refactor_iterations) is prepared in equal parts over steps n + 1 ... n + lag - 1 and
  /// used from step n + lag on, whatever the wall clock (1 = the next step, all at once).
  int refactor_lag_steps = 1;
  /// When > 0, a step asks for a new factor only when its CG also needs more than this many
  /// iterations beyond the first solve made with the factor in use (State::factor_baseline_cg):
  /// where the iterations come from the contact and spring terms, which no factor holds, a
  /// fresh factor does not bring them down and is not paid for. 0 (default): every step above
  /// refactor_iterations asks, the rule the scripted scenes and their goldens are tuned to
  /// (docs/contact-model.md, "Adaptive refactorisation trigger").
  int refactor_slack_iterations = 0;
  /// Divergence guard (sim::SolveDeformables): after a step's solve, a non-finite value or a
  /// soft-tissue or thread node faster than this means the solve diverged, mm/s. No tissue in
  /// an arthroscopy moves at 10 m/s; a diverged linearised solve gives 1e5 mm/s and more.
  double divergence_speed_mm_s = 1e4;
  /// A diverged step is undone and solved again in 2, 4, ... substeps, up to this many; a step
  /// that still diverges stops the run with a message (sim::SimulationError).
  int divergence_max_substeps = 16;
};

/// Contact parameters (scenario section `contact:`, all optional; docs/contact-model.md explains
/// each value). Defaults are the values the contact model was tuned with.
struct ContactOptions {
  double alarm_distance_mm = 1.0;    ///< gap below which a contact is handed to the solver, mm
  double contact_distance_mm = 0.1;  ///< gap the penalty keeps (skin), mm, < alarm_distance_mm
  double max_depth_mm = 1.5;         ///< deeper points count as passed through (stitches), mm
  double sweep_fraction = 0.5;       ///< tool sweep substep <= this * alarm_distance_mm, (0, 1]
  int max_substeps = 64;             ///< cap on tool sweep substeps per step
  double tool_tissue_stiffness_n_per_mm = 2.0;    ///< per contact point, N/mm
  double tool_thread_stiffness_n_per_mm = 2.0;    ///< per contact point, N/mm
  double tool_volume_stiffness_n_per_mm = 20.0;   ///< sharp point (awl), per plane, N/mm
  double thread_tissue_stiffness_n_per_mm = 1.0;  ///< per contact point (both sides), N/mm
  double tissue_tissue_stiffness_n_per_mm = 2.0;  ///< per contact point (both sides), N/mm
  double bone_stiffness_n_per_mm = 2.0;           ///< tissue-bone, bone tip-tissue, N/mm
  /// Thread-bone, per contact point, N/mm. A suture is never meant to enter bone (it runs out of
  /// the anchor's hole), so its bone contacts hold at any depth the search reaches
  /// (thread_bone_reach_mm) instead of letting go past max_depth as tissue contacts do; stiff
  /// enough that a limb pulled round the head by tens of newtons stays within ~1 mm of it.
  double thread_bone_stiffness_n_per_mm = 20.0;
  /// How far below the alarm band inside bone a thread node (not a segment interior) still
  /// finds the surface that pushes it out, mm.
  double thread_bone_reach_mm = 3.0;
  double tool_bone_stiffness_n_per_mm = 5.0;  ///< reaction on the kinematic tool, per part, N/mm
  /// Sharp points (awl) also hold the material they enter and their path's surface crossings
  /// (docs/contact-model.md "Sharp points"); false only to show what happens without.
  bool sharp_point_volume_contacts = true;
  /// Tissue-tissue contacts between different soft bodies; false only to show what happens
  /// without.
  bool tissue_tissue_contacts = true;
  /// Salient bone vertices (a spur tip) against soft triangles; false only to show the gap.
  bool bone_tip_contacts = true;
};

/// Largest ThreadSolverOptions::max_substep_levels (16 substeps per step).
inline constexpr int kMaxThreadSubstepLevels = 4;

/// Suture thread solver options (scenario section `thread_solver:`).
struct ThreadSolverOptions {
  double contact_stiffness_n_per_mm = 100.0;  ///< segment-segment penalty, N/mm
  /// Segment pairs within (1 + this) contact distances at the start of the step get a contact.
  double contact_margin_factor = 1.0;
  int max_newton_iterations = 8;  ///< per solve
  /// Adaptive substeps: a step whose thread solve ends unconverged is redone from its start as
  /// two steps of dt / 2, recursively up to this many levels (at most 2^levels substeps); the
  /// contact planes and spring anchors are held at the step's values. 0 = off.
  int max_substep_levels = 0;
  int max_active_set_passes = 4;  ///< contact active-set re-solves per Newton iteration
  /// Strain limit applied after the solve (a braided suture fails at ~5 % strain).
  double max_strain = 0.01;
  int strain_limit_passes = 100;      ///< passes of the strain-limit projection (tridiagonal)
  double newton_tolerance_mm = 1e-7;  ///< stop when the largest Newton update is below this, mm
  int max_ccd_rounds = 3;             ///< re-solves after continuous detection
  int ccd_samples = 8;                ///< distance samples per step in the swept test
  /// A swept distance below this * contact distance adds a contact.
  double ccd_close_fraction = 0.5;
  double crossing_tolerance_mm = 1e-4;  ///< distance at a coplanarity root counted as crossing
  /// Axial stiffness in compression / EA (a braid buckles).
  double compression_stiffness_fraction = 0.01;
  double speed_barrier_stiffness_n_per_mm = 100.0;  ///< penalty on moving beyond vmax dt, N/mm
  /// Same-thread segment pairs closer than this * diameter along the rest arc are skipped.
  double exclusion_factor = 1.5;
};

/// Haptic coupling of a handle (the device or scripted pose) to the simulated instrument, its
/// proxy (scenario section `haptics:`, all optional; docs/haptics.md). The proxy follows the
/// handle but stays outside bone; the force fed back is a spring-damper between the two plus the
/// soft-tissue reactions, clamped to max_force_n.
struct HapticsOptions {
  bool proxy = true;  ///< false: the instrument is the handle (no proxy)
  /// true (default): near bone the proxy slides along the surfaces it met (god-object contact
  /// planes, wedge push-out; docs/contact-model.md, "The tool proxy"); false: the earlier proxy,
  /// which advances 0.25 mm toward the handle and is pushed out again (it creeps along a face it
  /// presses into and stops short of the hand's projection at its iteration cap).
  bool slide = true;
  double coupling_stiffness_n_per_mm = 1.0;    ///< virtual coupling spring, N/mm
  double coupling_damping_n_s_per_mm = 0.002;  ///< virtual coupling damper, N*s/mm
  double max_force_n = 25.0;                   ///< clamp of the fed-back force magnitude, N
  /// Tissue pressed against bone under the instrument is kept at least this thick, mm; the
  /// instrument slides along the bone there only beyond trapped_friction (docs/haptics.md).
  /// 0: the earlier rule (advance along the push bounded per step, no floor, no friction).
  double trapped_gap_mm = 1.0;
  double trapped_friction = 0.5;  ///< Coulomb coefficient of that sliding (instrument on tissue)
};

/// Run options.
struct Options {
  double dt_s = 0.02;
  double duration_s = 1.0;
  Vec3 gravity_mm_s2{0.0, 0.0, -9810.0};
  std::uint64_t seed = 1;
  std::string output_file = "run.h5";
  int output_every_steps = 1;     ///< write a frame every N steps
  double flush_interval_s = 1.0;  ///< HDF5 flush at least this often in simulated time
  /// A full checkpoint of the State (for `run --resume` / `run --from`) is written at the first
  /// frame of every checkpoint_every_s of simulated time, s (and at the end of a run).
  double checkpoint_every_s = 5.0;
};

/// Everything a scenario defines. Immutable after loading.
struct Model {
  std::string name;
  std::string scenario_path;    ///< file it came from
  std::string scenario_text;    ///< exact YAML text (stored in HDF5 /meta/scenario_yaml)
  std::string scenario_sha256;  ///< hex digest of scenario_text
  Options options;
  SolverOptions solver;
  ContactOptions contact;
  OperationOptions operations;  ///< scenario `operations:`
  ThreadSolverOptions thread_solver;
  HapticsOptions haptics;  ///< scenario `haptics:`
  std::vector<Material> materials;
  std::vector<SoftBodyModel> soft_bodies;
  std::vector<BoneModel> bones;
  std::vector<ThreadModel> threads;
  std::vector<Join> joins;
  std::vector<Portal> portals;
  std::vector<InstrumentModel> instruments;
  CameraModel camera;
  std::vector<Landmark> landmarks;
  std::vector<Region> regions;

  /// Index of the soft body / bone / thread / instrument / landmark named `name`, or -1.
  int FindSoftBody(const std::string& name) const;
  int FindBone(const std::string& name) const;
  int FindThread(const std::string& name) const;
  int FindInstrument(const std::string& name) const;
  int FindLandmark(const std::string& name) const;
  int FindRegion(const std::string& name) const;
  int FindPortal(const std::string& name) const;
};

/// Lower-case scenario name of an instrument kind ("scorpion_needle"); inverse below.
const char* InstrumentKindName(InstrumentKind kind);
/// Parses a kind name; std::nullopt if unknown.
std::optional<InstrumentKind> ParseInstrumentKind(const std::string& name);

}  // namespace arthrosim
