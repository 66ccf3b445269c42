#pragma once
// Per-step scratch of the thread solver (internal to the thread solver files; public only so that
// the ThreadWorkspace can own it). Every buffer keeps its capacity between steps, so a step that
// needs no more contacts than an earlier one allocates nothing.
#include <array>
#include <cstdint>
#include <vector>

#include "arthrosim/core/types.h"
#include "arthrosim/physics/thread_band_solver.h"
#include "arthrosim/physics/thread_collision.h"

namespace arthrosim::physics {

/// One energy term acting on y = sum_k w_k x_k over up to four nodes (global indices).
///   kPlane:  0.5 k max(0, offset - n.y)^2           (contacts; self contact uses y = p - q)
///   kSpring: 0.5 k (|y - anchor| - length)^2        (segments, point springs, bending with L = 0)
///   kLimit:  0.5 k max(0, |y - anchor| - length)^2  (speed barrier: node within vmax dt of x0)
struct ThreadTerm {
  enum class Kind : std::uint8_t { kPlane, kSpring, kLimit };
  Kind kind = Kind::kSpring;
  int count = 0;
  std::array<int, 4> node{-1, -1, -1, -1};
  std::array<double, 4> w{0, 0, 0, 0};
  double k = 0;             ///< mN/mm
  double k_compress = -1;   ///< stiffness when shorter than its length; < 0 = same as k
  Vec3 vec = Vec3::Zero();  ///< normal (plane) or anchor (spring)
  double scalar = 0;        ///< offset (plane) or rest length (spring)
};

/// A segment (node n0 = node seg of `thread`, n1 = n0 + 1) in global numbering.
struct ThreadSegmentRef {
  int thread = 0;
  int seg = 0;
  int n0 = 0;
  int n1 = 0;
};

/// Scratch of StepThreads, global node numbering (threads concatenated).
struct ThreadScratch {
  int num_nodes = 0;
  std::vector<int> offset;  ///< first global node of each thread
  Points x0, v0, x, trial, dx;
  std::vector<int> dof;  ///< 0..num_free-1 for free nodes, -1 for fixed / dead
  std::vector<std::uint8_t> alive;
  std::vector<double> mass, inertia;  ///< kg; m (1 + alpha dt) / dt^2
  std::vector<ThreadSegmentRef> segments;
  std::vector<double> seg_diameter;
  std::vector<ThreadTerm> fixed_terms;         ///< bending, contacts, springs, limits
  std::vector<ThreadTerm> stretch_terms;       ///< one per alive segment, chain order
  std::vector<ThreadTerm> pair_terms;          ///< segment-segment contacts
  std::vector<std::array<int, 2>> pair_keys;   ///< sorted, parallel to pair_terms
  std::vector<int> contact_term, spring_term;  ///< index into fixed_terms or -1
  std::vector<double> lambda, lambda_new;      ///< stretch force per stretch term, mN
  std::vector<std::int8_t> switch_active;      ///< model activity of planes and speed barriers
  std::vector<Vec3> switch_dir;                ///< speed barrier: predicted direction
  int num_free = 0;
  double dt = 0;
  Vec3 gravity = Vec3::Zero();
  // Linear algebra.
  BandedBlockMatrix band;
  BandedBlockMatrix band_base;   ///< inertia, stretch and springs at the iterate (not factored)
  int base_cols = 0;             ///< off-band columns of the springs (first in cols_*)
  std::vector<Vec3> sw_y, sw_g;  ///< switching terms at the iterate: y and true gradient wrt y
  std::vector<Mat3> sw_h;        ///< switching terms at the iterate: Hessian wrt y
  std::vector<double> min_pivot, grad, rhs, step;
  // Independent groups of the Newton solve (connected components of the coupling terms: a
  // thread's chain, and threads joined by segment-segment contacts or multi-node terms). The
  // energy is a sum over groups, so each group has its own active set and line search.
  int num_groups = 0;
  std::vector<int> node_group;     ///< group of each node (union-find parent while building)
  std::vector<int> stretch_group;  ///< group of each stretch term
  std::vector<int> switch_group;   ///< group of each switching term (contact plane, barrier)
  std::vector<std::uint8_t> group_changed, group_consistent, group_done, group_converged,
      group_pending;
  std::vector<double> group_alpha, group_e0, group_e1, group_slope, group_step_max;
  std::vector<double> step_kept;    ///< per group: the step of its last consistent pass, or pass 0
  Points x_next;                    ///< the accepted iterate of every group
  std::vector<double> cols_node_w;  ///< off-band rank-1 columns: 4 weights each
  std::vector<int> cols_node;       ///< 4 nodes each
  std::vector<Vec3> cols_dir;       ///< direction * sqrt(k)
  std::vector<double> cols_v;       ///< B^-1 u for every column, 3 n each
  std::vector<double> cap_s;        ///< capacitance matrix I + U^T B^-1 U (m x m)
  std::vector<double> cap_y;
  // Broad phase and fail-safe.
  std::vector<Box3> boxes;
  std::vector<int> order;
  std::vector<std::array<int, 2>> pairs, kept;
  std::vector<std::uint8_t> frozen;
  // Strain projection (tridiagonal per chain).
  std::vector<double> tri_a, tri_b, tri_c, tri_r;
  std::vector<Vec3> tri_u;
  std::vector<std::uint8_t> tri_active;
  std::vector<double> tri_target;
  std::vector<int> tri_chain;  ///< first stretch term of each chain, then the term count
  std::vector<double> tri_w;   ///< inverse mass per node, 0 for nodes that do not move, 1/kg
  // Adaptive substeps: the start of the (sub)step at each substep level, positions and
  // velocities of every node (global numbering), restored when its solve ends unconverged.
  std::vector<Points> level_x, level_v;
};

}  // namespace arthrosim::physics
