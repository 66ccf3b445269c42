#pragma once
// All soft bodies of a Model solved as one linear corotational FEM system, advanced by one
// linearised implicit Euler step per time step (SOFA EulerImplicitSolver):
//   A dv = b,  A = (1 + h alpha) M + h (h + beta) K + h^2 C,
//              b = h (f - alpha M v) - h (h + beta) K v - h^2 C v,
//   v += dv,  x += h v,
// with K the corotational stiffness (rotations frozen for the step), C the linearised penalty
// contacts and springs, solved by block-Jacobi preconditioned CG warm-started from dv_warm.
//
// Unknowns live in "slots": body b owns the slot range [offset_b, offset_b + capacity_b) and
// node i of b sits in slot offset_b + i. A node joined to an earlier body (Model::joins) is an
// alias of that body's node and shares its slot. Every sum (forces, products, dot products,
// masses) runs in (body, node) / (body, tet) order, so results are a function of the State
// only: bit-identical for any thread count, and whether the system was built from scratch or
// updated incrementally after topology changes.
//
// Derived data only: lives in the sim Workspace, rebuilt by Build() after a restore.
#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "arthrosim/core/model.h"
#include "arthrosim/core/state.h"
#include "arthrosim/physics/block_ldlt.h"
#include "arthrosim/physics/block_sparse.h"
#include "arthrosim/physics/cg_solver.h"
#include "arthrosim/physics/contact.h"
#include "arthrosim/physics/corotational_fem.h"
#include "arthrosim/physics/soft_stages.h"

namespace arthrosim::physics {

class ArkodeIntegrator;

// The product and preconditioner choices are Model options (core/model.h, SolverOptions).
using arthrosim::Preconditioner;
using arthrosim::SystemProduct;

/// Energies of the soft bodies, micro-joules (mN mm = kg mm^2/s^2).
struct SoftEnergies {
  double kinetic_uj = 0;
  double elastic_uj = 0;
  double gravitational_uj = 0;  ///< -sum m g . x (zero at x = 0)
  double total() const { return kinetic_uj + elastic_uj + gravitational_uj; }
};

/// A body's node: (soft body index, node index).
struct NodeRef {
  std::int32_t body = -1;
  std::int32_t node = -1;
};

class SoftSystem final : public SoftStages {
 public:
  SoftSystem();
  ~SoftSystem();
  SoftSystem(SoftSystem&&) noexcept;
  SoftSystem& operator=(SoftSystem&&) noexcept;

  /// Builds everything from (model, state): joins, slots, element rest data, masses, pattern;
  /// takes the product, preconditioner and refactor_iterations from model.solver.
  void Build(const Model& model, const State& state);

  /// Advances every soft body by one step of model.options.dt_s with the integrator of
  /// model.solver. Contacts and springs targeting soft bodies enter the implicit system; their
  /// force outputs are filled. Does not advance state->time_s or state->step.
  /// Then, when the solve needed more than solver.refactor_iterations CG iterations, requests
  /// a new preconditioner factor of the end-of-step positions (Advance + RequestFactorAfter).
  SoftStepStats Step(const Model& model, ContactSet* contacts, SpringSet* springs, State* state);

  /// One step of h_s seconds (the scenario's dt or a substep of it), without requesting a new
  /// factor: stats.anchor_moved says one is due. The preconditioner is the one of the
  /// scenario's dt whatever h_s, so splitting a step never changes the factor state in State.
  SoftStepStats Advance(const Model& model, double h_s, ContactSet* contacts, SpringSet* springs,
                        State* state);
  /// Requests the factor a step's Advance found due (stats.anchor_moved), from the positions
  /// in *state; nothing when none is due or one is already being prepared.
  void RequestFactorAfter(const SoftStepStats& stats, State* state);

  /// Static equilibrium by a direct sparse solve (Eigen SimplicialLDLT) of the corotational
  /// system linearised at the current positions, repeated `iterations` times (1 from the rest
  /// state = linear elasticity). Gravity and elasticity only; sets velocities to zero.
  /// Returns the final relative force residual |f| / |f_gravity| on free nodes.
  double SolveStatic(const Model& model, State* state, int iterations = 1);

  // ---- Topology changes: update State and the derived data, cost ~ touched elements. ----

  /// Marks tets dead (cutting, shaving). Nodes left without an element drop out of the solve.
  void RemoveTets(int body, std::span<const std::int32_t> tets, State* state);
  /// Appends nodes to a body, each interpolating x, v, x_rest and dv_warm of up to four parent
  /// nodes with the given weights (sum 1). Returns the index of the first new node.
  std::int32_t AppendNodes(const Model& model, int body,
                           std::span<const std::array<std::int32_t, 4>> parents,
                           std::span<const std::array<double, 4>> weights, State* state);
  /// Appends alive tets (positively oriented at rest) to a body; returns the first new index.
  std::int32_t AppendTets(int body, std::span<const mesh::Tet> tets, State* state);
  /// Splits tet `tet` 1 -> 4 at the interior point of barycentric coordinates `bary`: one new
  /// node, the old tet removed, four tets appended. Returns the first new tet index.
  std::int32_t SplitTet(const Model& model, int body, std::int32_t tet,
                        const std::array<double, 4>& bary, State* state);
  /// Sets new rest positions (mm) for nodes of a body (plastic update after shaving); joined
  /// copies get the same rest position. Element rest data and masses follow.
  void SetRestPositions(int body, std::span<const std::int32_t> nodes, const Points& rest_mm,
                        State* state);

  // ---- Queries ----

  /// The settings Build took from model.solver (product, preconditioner, refactor_iterations).
  int refactor_iterations() const { return refactor_iterations_; }
  Preconditioner preconditioner() const { return preconditioner_; }
  SystemProduct product() const { return product_; }
  /// Lumped mass of a node (kg); 0 when it has no alive, non-degenerate element.
  double NodeMass(int body, std::int32_t node) const;
  /// Sum of all slot masses (kg), shared nodes counted once.
  double TotalMass() const;
  /// Sum of rest volumes of alive, non-degenerate tets of a body (mm^3).
  double AliveVolume(int body) const;
  /// True when the node is an unknown of the solve (has an element and is not fixed).
  bool IsFree(int body, std::int32_t node) const;
  /// The node whose slot this node shares (itself unless it is a joined alias).
  NodeRef Owner(int body, std::int32_t node) const;
  /// True when the node's slot is shared with another body (scenario `joins`), either side.
  bool IsJoined(int body, std::int32_t node) const;
  /// Kinetic, elastic (rotations recomputed from state) and gravitational energy.
  SoftEnergies ComputeEnergies(const Model& model, const State& state) const;
  /// Elastic force (mN) on every node of a body at the state's positions (0 on dead nodes).
  Points ElasticForces(const Model& model, const State& state, int body) const;
  std::int32_t slot_count() const { return slots_; }

  // ---- Stages of an external integrator (SoftStages; see soft_stages.h) ----

  std::int32_t stage_slots() const override { return slots_; }
  void BeginExternalStep(const State& state, Eigen::Ref<Eigen::VectorXd> x_mm,
                         Eigen::Ref<Eigen::VectorXd> v_mm_s) override;
  void EvaluateRates(const Model& model, const Eigen::VectorXd& x_mm, const Eigen::VectorXd& v_mm_s,
                     ContactSet* contacts, SpringSet* springs, Eigen::Ref<Eigen::VectorXd> dx,
                     Eigen::Ref<Eigen::VectorXd> dv) override;
  CgResult SolveNewtonSystem(const Model& model, double gamma_s, const Eigen::VectorXd& xz_mm,
                             const Eigen::VectorXd& bx, const Eigen::VectorXd& bv,
                             ContactSet* contacts, SpringSet* springs,
                             Eigen::Ref<Eigen::VectorXd> ox,
                             Eigen::Ref<Eigen::VectorXd> ov) override;
  SoftStepStats FinishExternalStep(const Model& model, const Eigen::VectorXd& x_mm,
                                   const Eigen::VectorXd& v_mm_s, const Eigen::VectorXd& v_old_mm_s,
                                   ContactSet* contacts, SpringSet* springs, State* state) override;

 private:
  struct ElemRef {
    std::int32_t body;
    std::int32_t tet;
    bool operator<(const ElemRef& o) const { return body != o.body ? body < o.body : tet < o.tet; }
    bool operator==(const ElemRef& o) const { return body == o.body && tet == o.tet; }
  };
  struct Body {
    Lame lame;
    double density = 0;  // kg/mm^3
    double alpha = 0;    // 1/s
    double beta = 0;     // s
    std::int32_t offset = 0;
    std::int32_t capacity = 0;
    std::int32_t model_nodes = 0;     // nodes present in the Model (join candidates)
    std::vector<std::int32_t> slot;   // per node
    std::vector<std::uint8_t> owner;  // per node
    std::vector<TetRest> rest;        // per tet
    std::vector<std::array<std::int32_t, 4>> tet_slot;
    std::vector<std::array<std::int32_t, 6>> tet_pair;  // block index per edge, -1 if dead
    std::vector<std::uint8_t> alive;                    // per tet, copy of state
    std::vector<Mat3> rotation;                         // per tet, this step
    std::vector<std::array<Vec3, 4>> force;             // per tet, this step
  };
  // A linearised contact or spring: stiffness matrix k (mN/mm) on the point sum_i w_i x_i.
  struct PointTerm {
    std::array<std::int32_t, 4> slot{-1, -1, -1, -1};
    std::array<double, 4> w{0, 0, 0, 0};
    Mat3 k = Mat3::Zero();
  };

  // Layout and bookkeeping.
  void Layout(const Model& model, const State& state);
  void LayoutBodies(const Model& model, const State& state);
  void LayoutSlots();
  void MatchJoins(const Model& model, const State& state);
  void MarkFixedNodes(const Model& model);
  void ResetStepVectors();
  void AddElement(int body, std::int32_t tet, const SoftBodyState& sb);
  void RemoveElement(int body, std::int32_t tet);
  void RecomputeSlot(std::int32_t slot);
  void RefreshRest(int body, std::int32_t tet, const SoftBodyState& sb);
  bool NeedsRebuild(int body, std::int32_t new_nodes) const;

  // Step stages (the built-in implicit Euler and the external stages above use them).
  void Gather(const State& state);
  void ComputeRotationsAndForces(const Eigen::VectorXd& x);
  void AddGravity(const Model& model);
  void AssembleStiffness(double scale_h, double h, bool assembled);
  void BuildPointTerms(const Model& model, const Eigen::VectorXd& x, ContactSet* contacts,
                       SpringSet* springs, bool add_forces);
  // The preconditioner of this step: the warped anchored factor (switching to a prepared one
  // at State::factor_switch_step, preparing one part of it otherwise), block Jacobi for free
  // slots the factor does not cover or when there is none.
  void BuildPreconditioner(double h, State* state);
  // After a solve (dv_): contacts apart at the start of the step (force_n == 0) whose point
  // ends the step behind its plane get their term, force and right-hand side (b_) share, and
  // force_n = -1. True if any did.
  bool ActivateCrossedContacts(double h, ContactSet* contacts);
  // Re-solves per step for contacts crossed within it (see Step).
  static constexpr int kCrossRounds = 2;
  void BuildBlockJacobi(double h);
  // Anchored factors (soft_factor.cpp). A factor is a pure function of its source (per body:
  // the factored mesh's rest positions and alive tets, the anchor positions), h and the slot
  // layout.
  struct FactorBuild {
    BlockLdlt ldlt;
    std::vector<std::int32_t> compact;               // per slot: factor node, -1 if not in it
    std::vector<std::int32_t> nodes;                 // factor node -> slot
    std::vector<std::array<std::int32_t, 2>> pairs;  // factor node pairs (i < j), sorted
    std::vector<std::int32_t> row_start;             // pairs of node i: [row_start[i], [i + 1])
    std::vector<Mat3> anchor_rot;                    // per slot node rotation at the anchor
    std::vector<Mat3> diag, offdiag;                 // values per factor node / per pair
    double h = -1;
    bool analysed = false;  // ldlt holds the pattern of nodes and pairs
  };
  struct FactorSource {
    const Points* rest = nullptr;
    const std::vector<std::uint8_t>* alive = nullptr;
    const Points* anchor = nullptr;
    const std::vector<mesh::Tet>* tets = nullptr;  // the state's tets (its prefix is the mesh)
  };
  // Views of State for StartFactor (in scratch_sources_: valid until the next call).
  const std::vector<FactorSource>& ActiveSources(const State& state);
  const std::vector<FactorSource>& PendingSources(const State& state);
  void StartFactor(const std::vector<FactorSource>& src, double h, FactorBuild* f);
  void FactorPattern(const std::vector<FactorSource>& src, FactorBuild* f);
  void FactorValues(const std::vector<FactorSource>& src, double h, FactorBuild* f);
  // Numeric parts of a prepared factor (the part count is a function of the lag only).
  int FactorParts() const;
  void AdvancePending(const State& state, double h, bool all);
  void SwitchFactor(double h, State* state);
  // Before an edit of tet_alive / x_rest: the active factor's source keeps the old values.
  void KeepFactorSource(SoftBodyState* sb) const;
  void RequestFactor(State* state);
  std::int32_t CountUncovered() const;            // free slots the active factor does not cover
  void ReplaceFactorNow(double h, State* state);  // factor this step's mesh at once
  void WarpFactor();
  void Precondition(const Eigen::VectorXd& r, Eigen::VectorXd* z) const;
  void ApplyStiffness(const Eigen::VectorXd& x, Eigen::VectorXd* y) const;  // Kh x (scaled)
  // Element-by-element sum_b scales[b] K_b x (free rows only).
  void ApplyElementStiffness(const Eigen::VectorXd& x, const std::vector<double>& scales,
                             Eigen::VectorXd* y) const;
  void ApplyPointTerms(double scale, const Eigen::VectorXd& x, Eigen::VectorXd* y) const;
  void ApplySystem(const Eigen::VectorXd& x, Eigen::VectorXd* y) const;
  void Scatter(State* state) const;
  void FillOutputs(const Model& model, ContactSet* contacts, SpringSet* springs) const;

  std::vector<Body> bodies_;
  std::int32_t slots_ = 0;
  // Per slot.
  std::vector<NodeRef> slot_node_;                  // owner copy, body -1 for a gap
  std::vector<std::vector<NodeRef>> slot_aliases_;  // joined copies other than the owner
  std::vector<std::vector<ElemRef>> incident_;      // alive tets touching the slot, sorted
  std::vector<double> mass_;                        // kg
  std::vector<double> alpha_mass_;                  // kg/s
  std::vector<std::uint8_t> fixed_;
  std::vector<std::uint8_t> free_;  // unknown of the solve
  BlockSparseMatrix kmat_;          // h (h + beta) K, assembled mode

  // Step scratch (3 * slots_).
  Eigen::VectorXd x_, v_, f_, b_, dv_, tmp_;
  CgScratch cg_scratch_;
  std::vector<Mat3> precond_;    // inverse diagonal blocks per slot
  std::vector<Mat3> node_rot_;   // per slot rotation for the warped rest factor
  std::vector<Mat3> node_sum_;   // per slot sum of incident element rotations (scratch)
  double h_ = 0;                 // step of the current system
  std::vector<double> kscales_;  // per body scale of K in the system
  std::vector<PointTerm> terms_;
  SystemProduct product_ = SystemProduct::kAssembled;
  Preconditioner preconditioner_ = Preconditioner::kRestCholesky;
  // Anchored factors (kRestCholesky): the one in use and the one being prepared.
  FactorBuild active_, pending_;
  bool active_ready_ = false;           // active_ built from State's source (false after Build)
  int pending_units_ = 0;               // work units of the requested factor done (start + parts)
  std::int32_t uncovered_ = 0;          // free slots the active factor does not cover (Jacobi)
  mutable Eigen::VectorXd pw_;          // factor work vector of the solve
  const State* stage_state_ = nullptr;  // the state of the external integrator's step
  // Scratch of FactorPattern / FactorValues (kept: a refactorisation allocates nothing unless
  // the pattern changed).
  std::vector<std::uint8_t> scratch_has_;
  std::vector<std::array<std::int32_t, 2>> scratch_edges_, scratch_pairs_;
  std::vector<std::int32_t> scratch_nodes_, scratch_row_at_, scratch_cols_;
  std::vector<double> scratch_mass_, scratch_alpha_mass_;
  std::vector<FactorSource> scratch_sources_;
  bool refactored_ = false;  // this step built or switched to a new factor
  // This step put a factor of a new source into use (a switch, a factor of the step's own mesh,
  // the first factor of a run): not the rebuild of the one in use after a restore.
  bool new_factor_source_ = false;
  bool factor_work_ = false;  // this step did factor work (a part or a whole factor)
  double factor_ms_ = 0;
  int refactor_iterations_ = 10;  // from SolverOptions::refactor_iterations
  int refactor_lag_ = 1;          // from SolverOptions::refactor_lag_steps
  int refactor_slack_ = 0;        // from SolverOptions::refactor_slack_iterations (0: off)
  std::unique_ptr<ArkodeIntegrator> arkode_;
};

}  // namespace arthrosim::physics
