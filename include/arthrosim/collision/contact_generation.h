#pragma once
// The collision stage of a step: from (Model, State, previous tool poses) to the ContactSet the
// solvers take, the tool-bone reaction forces, and afterwards the tool forces and contact
// events. See docs/contact-model.md for the model and its parameters.
//
// Where it sits in the sim step (src/sim/step.cpp is the reference for the order):
//   prev_tools = state.tools, then the tool kinematics move state.tools to this step's pose
//   Detect(model, state, prev_tools, params, &world, &out)    tissue and threads at t_n
//   the constraint springs are built, the soft and thread solvers take out.contacts and fill
//   their force_n
//   state.tools[s].force_n = ToolForces(out)[s] minus the reactions of tool-held springs
//   the clock advances, then UpdateContactEvents(model, state, out, &state.tool_contacts,
//   &state.events) and the instrument actions
// CollisionWorld is Workspace (trees, surfaces, work lists): rebuilding it from any State gives
// the same contacts bit for bit, so it need not be saved. state.tool_contacts (the last step's
// touching (tool, body) pairs) must be in State: the events of the next step depend on it.
#include <array>
#include <cstdint>
#include <vector>

#include "arthrosim/collision/collision_mesh.h"
#include "arthrosim/collision/contact_scratch.h"
#include "arthrosim/collision/instrument_shape.h"
#include "arthrosim/core/model.h"
#include "arthrosim/core/state.h"
#include "arthrosim/physics/contact.h"

namespace arthrosim::collision {

/// Contact parameters: the Model's contact options (core/model.h, scenario section `contact:`;
/// docs/contact-model.md explains each choice). Tests may pass changed copies.
using CollisionParams = ContactOptions;

/// The parameters of a scenario's `contact:` section (a copy of `contact`).
CollisionParams ParamsFromModel(const ContactOptions& contact);

/// Bone triangles near each query slot (soft surface vertices, thread nodes and segments): the
/// list of every triangle whose box overlaps a `wide` box (the query box when it was made, grown
/// by a slack). While a slot's query box stays inside its wide box, filtering the list with the
/// query box gives exactly what a tree query would (bones are static between reshapes): a cache
/// that never changes a result.
struct NearBoneCache {
  std::int64_t bone_version = -1;  ///< BoneEntry::version the lists were made for
  std::vector<Box> wide;           ///< box each list was made for, mm
  std::vector<std::uint8_t> valid;
  std::vector<std::vector<std::int32_t>> tris;  ///< ascending bone triangle indices
  /// Tissue-bone only: a slot found clearly out of contact at position far_at[i] needs no new
  /// search while it stays within far_margin[i] (mm) of it (the signed distance to a closed
  /// static surface changes by at most the distance moved); far_margin < 0 = no such bound.
  std::vector<Vec3> far_at;
  std::vector<double> far_margin;
  /// Nearest triangle found for each slot last time (-1 = none): tested first next time, which
  /// only saves tests (see NearestOnSurface).
  std::vector<std::int32_t> hint;
};

/// Out-of-reach bounds for query points against a moving surface (temporal coherence that never
/// changes a result): point i, found at least margin[i] + reach from the surface when it was at
/// at[i] and the surface had drifted drift0[i] (cumulative max vertex displacement), cannot be
/// within reach while |p - at[i]| + (drift - drift0[i]) < margin[i] (distance to a moving
/// triangle surface changes by at most the point's motion plus the largest vertex motion).
struct FarBounds {
  std::int64_t key_a = -1, key_b = -1;  ///< versions of the two sides the bounds were made for
  std::vector<Vec3> at;
  std::vector<double> margin;  ///< mm; <= 0 = no bound
  std::vector<double> drift0;
  /// Clears the bounds unless they were made for (a, b) with n points.
  void Reset(std::int64_t a, std::int64_t b, std::size_t n) {
    if (key_a == a && key_b == b && margin.size() == n) return;
    key_a = a;
    key_b = b;
    at.assign(n, Vec3::Zero());
    margin.assign(n, -1.0);
    drift0.assign(n, 0.0);
  }
  /// True if point i at p is still provably out of reach of a surface that has drifted `drift`.
  bool Holds(std::size_t i, const Vec3& p, double drift) const {
    return margin[i] > 0 && (p - at[i]).norm() + (drift - drift0[i]) < margin[i];
  }
};

/// Derived collision data (surfaces, trees): Workspace, rebuilt from State at will.
struct CollisionWorld {
  struct SoftEntry {
    std::size_t tet_count = 0;
    std::vector<std::uint8_t> alive;  ///< tet_alive the surface was built for
    Surface surface;
    std::vector<Vec3> positions;  ///< local vertex positions this step
    TriangleBvh bvh;
    bool built = false;
    std::vector<NearBoneCache> near_bone;  ///< per bone, per local surface vertex
    std::vector<std::uint8_t> fixed;       ///< per local surface vertex: a Model fixed node
    /// Per other soft body joined to this one (empty if not joined): per local surface vertex,
    /// 1 = near the join at rest (no contact against that body), and per local triangle, 1 = it
    /// touches a joined node (an interface or rim triangle: never an obstacle for that body).
    std::vector<std::vector<std::uint8_t>> join_vertex, join_tri;
    std::int64_t version = 0;  ///< increases at every surface rebuild
    /// Sum over refits of the largest surface vertex displacement, mm (FarBounds drift).
    double drift_mm = 0;
    bool refit_pending = false;       ///< SyncWorld's mark between its rebuild and refit passes
    std::vector<FarBounds> far_soft;  ///< per other soft body, per local surface vertex
  };
  struct BoneEntry {
    mesh::TriMesh surface;  ///< copy the tree was built for
    Surface indexed;        ///< local numbering
    std::vector<Vec3> positions;
    TriangleBvh bvh;
    bool built = false;
    bool closed = false;         ///< every edge shared by exactly two triangles (signed distance)
    std::uint64_t revision = 0;  ///< BoneState::revision of the surface it was built from
    std::int64_t version = 0;    ///< increases at every (re)build
    /// Local vertices that stick out (a convex corner sharper than the smooth tessellation of a
    /// bone: a spur tip), ascending; they also meet soft triangles (BoneTipTissue).
    std::vector<std::int32_t> salient;
    std::vector<FarBounds> far_soft;  ///< per soft body, per salient vertex
  };
  struct ThreadEntry {
    std::vector<NearBoneCache> near_bone;  ///< per bone, per thread node then segment
    /// Per soft body, per thread node then segment: last nearest triangle (a search hint only).
    std::vector<std::vector<std::int32_t>> soft_hint;
  };
  std::vector<SoftEntry> soft;
  std::vector<BoneEntry> bones;
  std::vector<ThreadEntry> threads;
  std::int64_t rebuilds = 0;  ///< tree (re)builds so far (diagnostics)
  /// Work lists of Detect (per task, merge, sort): kept so a steady step allocates nothing.
  DetectScratch scratch;
};

/// Brings the world up to date with `state`: refits soft-body trees, rebuilds those whose
/// topology (tets / tet_alive) changed and bones whose surface changed.
void SyncWorld(const Model& model, const State& state, CollisionWorld* world);

/// Which body a tool touches.
struct BodyRef {
  ConstraintEnd::Kind kind = ConstraintEnd::Kind::kSoftBody;  ///< kSoftBody, kThread or kBone
  std::int32_t index = -1;
};

/// Result of the detection stage.
struct CollisionOutput {
  physics::ContactSet contacts;  ///< sorted by (tool, target, index, obstacle, nodes)
  /// Obstacle kind per contact (parallel to contacts): kWorld for tools, else the obstacle body.
  std::vector<ConstraintEnd::Kind> obstacle_kind;
  std::array<Vec3, kToolSlots> bone_force_n{Vec3::Zero(), Vec3::Zero()};  ///< tool-bone, N
  /// (tool slot, bone) pairs touching this step with their deepest point (tool-bone only; the
  /// deformable pairs come from the solved contacts).
  std::vector<ToolContact> bone_touches;
  std::int32_t substeps[kToolSlots] = {0, 0};  ///< tool sweep substeps used
};

/// The collision stage: SyncWorld, then all contacts for this step. `state.tools` holds this
/// step's tool poses, `prev_tools` last step's (same array if unknown); deformables are at t_n.
void Detect(const Model& model, const State& state,
            const std::array<ToolState, kToolSlots>& prev_tools, const CollisionParams& params,
            CollisionWorld* world, CollisionOutput* out);

/// Contact force on each tool slot, N: minus the sum of force_n * normal of its contacts (the
/// solver filled force_n) plus the tool-bone reaction.
std::array<Vec3, kToolSlots> ToolForces(const CollisionOutput& out);

/// Work lists of UpdateContactEvents, kept by the caller so a step need not allocate.
struct ContactEventScratch {
  std::vector<ToolContact> now;
  std::vector<double> weight;
};

/// Compares this step's touching (tool, body) pairs (solved contacts with force_n > 0, and
/// tool-bone touches) with *touching (last step's), appends contact_start / contact_end events
/// (detail "region=<name>" if the contact point is in a Model region of that body) to *events,
/// and replaces *touching with this step's pairs (sorted). scratch (optional) is reused.
void UpdateContactEvents(const Model& model, const State& state, const CollisionOutput& out,
                         std::vector<ToolContact>* touching, std::vector<Event>* events,
                         ContactEventScratch* scratch = nullptr);

}  // namespace arthrosim::collision
