#pragma once
// Shared by the files of the thread solver (not installed). StepThreads (thread_chain.cpp) runs
// the stages; the Newton solve with its banded matrix and the length projection live in
// thread_newton.cpp, the point and segment-pair terms and the broad phase in thread_pairs.cpp.
#include <array>
#include <cstdint>
#include <vector>

#include "arthrosim/physics/thread_chain.h"
#include "arthrosim/physics/thread_collision.h"
#include "arthrosim/physics/thread_geometry.h"

namespace arthrosim::physics::thread_internal {

using Term = ThreadTerm;
using System = ThreadScratch;

// y = sum_k w_k x_k of a term.
[[gnu::always_inline]] inline Vec3 TermY(const Term& t, const Points& x) {
  Vec3 y = Vec3::Zero();
  for (int k = 0; k < t.count; ++k) y += t.w[k] * x.col(t.node[k]);
  return y;
}

// Energy, gradient wrt y, and the positive semi-definite Hessian wrt y of one term.
[[gnu::always_inline]] inline double TermEval(const Term& t, const Vec3& y, Vec3* g, Mat3* h) {
  if (t.kind == Term::Kind::kPlane) {
    const double pen = t.scalar - t.vec.dot(y);
    if (pen <= 0) {
      if (g) g->setZero();
      if (h) h->setZero();
      return 0;
    }
    if (g) *g = -t.k * pen * t.vec;
    if (h) *h = t.k * t.vec * t.vec.transpose();
    return 0.5 * t.k * pen * pen;
  }
  const Vec3 d = y - t.vec;
  if (t.scalar == 0) {
    if (g) *g = t.k * d;
    if (h) *h = t.k * Mat3::Identity();
    return 0.5 * t.k * d.squaredNorm();
  }
  const double l = d.norm();
  const double ext = l - t.scalar;
  if (t.kind == Term::Kind::kLimit && ext <= 0) {
    if (g) g->setZero();
    if (h) h->setZero();
    return 0;
  }
  if (l < 1e-12) {
    if (g) g->setZero();
    if (h) *h = t.k * Mat3::Identity();
    return 0.5 * t.k * ext * ext;
  }
  const Vec3 u = d / l;
  const double k = (ext < 0 && t.k_compress >= 0) ? t.k_compress : t.k;
  if (g) *g = k * ext * u;
  if (h) {
    const Mat3 uu = u * u.transpose();
    *h = k * (uu + std::max(0.0, 1.0 - t.scalar / l) * (Mat3::Identity() - uu));
  }
  return 0.5 * k * ext * ext;
}

// Newton with a backtracking line search on the incremental potential of the step, from *x
// (see thread_newton.cpp). Returns the iteration count; *converged tells whether the update
// fell below p.newton_tolerance_mm.
int NewtonSolve(System* s, const ThreadSolverParams& p, Points* x, bool* converged);

// Projects segments longer than (1 + max_strain) L0 back to that length (mass-weighted, other
// segments keep their length). Returns the number of segments limited.
int LimitStrain(System* s, double max_strain, int passes, Points* x);

// Fills *t with the nodes and weights of a point term on (thread, nodes, weights); false if it
// touches a dead node. Throws std::invalid_argument for a node beyond thread_nodes.
bool PointTerm(const System& s, int thread, const std::array<std::int32_t, 4>& nodes,
               const std::array<double, 4>& weights, int thread_nodes, Term* t);

// Contact term for segments a, b from their closest points cp; a0..b1 are the end points the
// closest points were computed on (used only for the normal of touching segments).
Term SegmentPairTerm(const System& s, int a, int b, double stiffness, const SegmentClosest& cp,
                     const Vec3& a0, const Vec3& a1, const Vec3& b0, const Vec3& b1);

// Segments a and b moving from s.x0 to x1.
SweptSegments Swept(const System& s, int a, int b, const Points& x1);

// Segment pairs whose swept boxes (x0 -> x1, grown by pad_factor * radius) overlap and that are
// not excluded, into s->kept (sorted).
void CandidatePairs(System* s, const std::vector<ThreadModel>& models,
                    const std::vector<ThreadRest>& rest, const ThreadSolverParams& p,
                    const Points& x1, double pad_factor);

}  // namespace arthrosim::physics::thread_internal
