#pragma once
// Suture threads as implicit mass-spring chains (paper section II: nodes joined by springs,
// node speed capped against haptic jitter).
//
// Each thread is a chain of nodes 0-1-...-n-1 with lumped masses (rho * A * L / 2 per segment
// end). Energy terms: axial springs k = EA / L0 per segment, a quadratic discrete bending energy
// 0.5 * EI / Lbar * |e_i / L_i - e_(i-1) / L_(i-1)|^2 (rotation invariant, exact for a straight
// rest shape and inextensible segments, constant Hessian), gravity, mass-proportional damping,
// one-sided penalty contacts (PointContact), springs to anchors (PointSpring), and segment-segment
// penalty contacts within and between threads at distance (d_a + d_b) / 2.
//
// Time stepping is backward Euler written as the minimisation of the incremental potential
//   E(x) = sum_i m_i [ (1 + alpha dt) |x_i - x0_i|^2 / (2 dt^2) - (x_i - x0_i).v0_i / dt
//                      - g.(x_i - x0_i) ] + U(x),   v1 = (x1 - x0) / dt,
// solved by Newton from x0 with an Armijo line search, so every iterate lowers E and a step cut
// short by the iteration limit is still stable. E is a sum over independent groups (threads not
// joined by a contact or a multi-node term), and each group has its own active set, line-search
// factor and convergence test. Each Newton matrix is block-pentadiagonal per
// chain (inertia, stretch, bending, point contacts and springs) and is factored by a banded
// block Cholesky in O(n); segment-segment contacts are rank-1 columns added by a Woodbury
// capacitance matrix. Three things make Newton converge on a moving, nearly inextensible chain
// (stiffness / nodal inertia ~ 1e10): (1) the transverse stiffness of a segment uses its
// stretch multiplier lambda / l (I - u u^T) (the Hessian of the Lagrangian, as in SQP), not
// k (1 - L / l), which explodes once a step rotates a stiff segment; compressed segments keep
// their negative term unless the factorisation finds the matrix indefinite; (2) the line
// search projects the trial lengths onto their linearised values (second-order correction,
// without which the energy rejects every rotating step); (3) contact planes and speed barriers
// get the activity predicted at the step (primal-dual active set, a few re-solves), so a
// thread landing on tissue does not discover its contacts one per iteration. A braid buckles
// instead of resisting compression: axial stiffness in compression is a small fraction of EA.
// After the solve, segments stretched beyond max_strain (1 %; FiberWire fails at ~5 %, a 1 N
// pull stretches 0.02 %) are projected back (tridiagonal fast projection per chain).
//
// Speed cap (paper: anti-jitter limit): a one-sided penalty inside the solve keeps each node
// within max_speed dt of its start (so the chain keeps its length while slowed), and the stored
// velocity is clamped to max_speed.
//
// Collision: a sorted sweep-and-prune over segment boxes (keys: min x, then segment id), exact
// segment-segment closest points, contacts linearised with normal and closest-point parameters
// frozen for the step. After each solve the motion x0 -> x1 is tested continuously (cubic
// coplanarity roots + sampling); pairs that come too close get a contact and the step is
// re-solved. If a crossing survives max_ccd_rounds, every thread involved is reverted to x0
// (velocity 0) until no pair crosses: x0 is crossing-free, so this is a guarantee, at the price
// of a momentary stick (only seen when a pull far beyond the suture's strength drags one
// thread through another).
//
// Units: mm, s, kg; force mN. Model fields in N (EA), N*mm^2 (EI), N/mm are converted here.
#include <cstdint>
#include <vector>

#include "arthrosim/core/model.h"
#include "arthrosim/core/state.h"
#include "arthrosim/physics/contact.h"
#include "arthrosim/physics/thread_scratch.h"

namespace arthrosim::physics {

/// Thread solver settings: the Model's thread-solver options (core/model.h, scenario section
/// `thread_solver:`). Tests may set changed copies in ThreadWorkspace::params.
using ThreadSolverParams = ThreadSolverOptions;

/// Immutable per-thread data derived from the ThreadModel (lives in the sim Workspace).
struct ThreadRest {
  std::vector<double> rest_length_mm;  ///< per segment i = (node i, node i+1), mm
  std::vector<double> arc_mm;          ///< rest arc length from node 0 to node i, mm
  std::vector<double> mass_kg;         ///< lumped mass per node, kg
  std::vector<std::uint8_t> fixed;     ///< 1 if the node is in ThreadModel::fixed_nodes
};

/// What the last StepThreads did (diagnostics, benchmarks).
struct ThreadStepStats {
  int newton_iterations = 0;     ///< over all solves of the step, discarded ones included
  int solves = 0;                ///< per kept (sub)step: 1 + re-solves after continuous detection
  int contact_pairs = 0;         ///< segment-segment contacts in the final solve
  int frozen_nodes = 0;          ///< nodes reverted by the crossing fail-safe
  int speed_capped_nodes = 0;    ///< nodes whose stored velocity was clamped to the cap
  int max_newton_per_solve = 0;  ///< largest Newton iteration count of one solve
  int unconverged_solves = 0;    ///< solves stopped by max_newton_iterations (kept substeps)
  int substeps = 0;              ///< (sub)steps kept: 1 unless adaptive substeps split it
  int discarded_solves = 0;      ///< solves of (sub)steps redone as two halves
  int strain_limited_segments = 0;  ///< segments shortened to (1 + max_strain) L0
};

/// Derived data and scratch for all threads; build once with InitThreadWorkspace.
struct ThreadWorkspace {
  ThreadSolverParams params;
  std::vector<ThreadRest> rest;  ///< parallel to Model::threads
  ThreadStepStats last;
  ThreadScratch scratch;  ///< buffers reused by every step (no steady-state allocation)
};

/// Rest data of one thread. Throws std::invalid_argument if the mesh is not a chain 0-1-...-n
/// (edges, when given, must be exactly (i, i+1)) or a segment has zero length.
ThreadRest MakeThreadRest(const ThreadModel& model);

/// Fills ws->rest for every thread of the model (keeps ws->params; the sim sets them from
/// Model::thread_solver).
void InitThreadWorkspace(const std::vector<ThreadModel>& threads, ThreadWorkspace* ws);

/// Advances every thread by dt_s (s) under gravity (mm/s^2), the PointContacts and PointSprings
/// whose target is kThread (others are ignored), self- and thread-thread collision. Fills the
/// force outputs of the thread contacts/springs (N, from the end-of-step positions). Fixed nodes
/// keep their position with zero velocity; dead nodes (node_alive == 0) are left untouched.
/// With ws->params.max_substep_levels > 0, a step whose solve ends unconverged is redone from
/// its start as two steps of dt_s / 2, recursively (contacts and spring anchors held); the force
/// outputs are then those of the last substep. Throws std::invalid_argument if the levels are
/// outside [0, kMaxThreadSubstepLevels].
void StepThreads(const std::vector<ThreadModel>& threads, double dt_s, const Vec3& gravity_mm_s2,
                 ContactSet* contacts, SpringSet* springs, std::vector<ThreadState>* states,
                 ThreadWorkspace* ws);

/// Kinetic + stretch + bending + gravity energy of one thread (alive nodes), kg*mm^2/s^2 (uJ);
/// gravity potential measured from z = 0 along -gravity.
double ThreadEnergy(const ThreadModel& model, const ThreadRest& rest, const ThreadState& state,
                    const Vec3& gravity_mm_s2);

/// Current length of the alive part of the chain, mm.
double ThreadLength(const ThreadState& state);

}  // namespace arthrosim::physics
