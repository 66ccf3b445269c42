#pragma once
// Helpers shared by the thread tests: building threads and an independent crossing check.
#include <cmath>
#include <vector>

#include "arthrosim/core/model.h"
#include "arthrosim/core/state.h"
#include "arthrosim/physics/contact.h"

namespace arthrosim::physics::testing {

/// A thread through the given polyline vertices, `per_leg` equal segments per leg.
inline ThreadModel PolylineThread(const std::vector<Vec3>& corners, int per_leg) {
  ThreadModel m;
  m.name.assign(1, 't');  // not = "t": GCC 12 -Wrestrict false positive
  std::vector<Vec3> pts;
  for (std::size_t c = 0; c + 1 < corners.size(); ++c)
    for (int k = 0; k < per_leg; ++k)
      pts.push_back(corners[c] +
                    (corners[c + 1] - corners[c]) * (static_cast<double>(k) / per_leg));
  pts.push_back(corners.back());
  m.initial.nodes.resize(3, static_cast<Eigen::Index>(pts.size()));
  for (std::size_t i = 0; i < pts.size(); ++i) m.initial.nodes.col(i) = pts[i];
  for (std::size_t i = 0; i + 1 < pts.size(); ++i)
    m.initial.edges.push_back({static_cast<std::int32_t>(i), static_cast<std::int32_t>(i + 1)});
  return m;
}

inline ThreadState RestState(const ThreadModel& m) {
  ThreadState s;
  s.x = m.initial.nodes;
  s.v = Points::Zero(3, m.initial.nodes.cols());
  s.node_alive.assign(m.initial.nodes.cols(), 1);
  return s;
}

/// A point contact or spring (`P`) on node `node` of thread `thread` alone.
template <class P>
P OnThreadNode(int thread, int node, double stiffness_n_per_mm) {
  P p;
  p.target = PointContact::Target::kThread;
  p.index = thread;
  p.nodes = {node, -1, -1, -1};
  p.weights = {1, 0, 0, 0};
  p.stiffness_n_per_mm = stiffness_n_per_mm;
  return p;
}

/// A point contact holding node `node` of thread `thread` above the plane z = 0.
inline PointContact FloorContact(int thread, int node, double stiffness_n_per_mm) {
  PointContact c = OnThreadNode<PointContact>(thread, node, stiffness_n_per_mm);
  c.normal = Vec3::UnitZ();
  c.offset_mm = 0;
  return c;
}

/// A spring on node `node` of thread `thread`; the caller sets its anchor.
inline PointSpring NodeSpring(int thread, int node, double stiffness_n_per_mm) {
  return OnThreadNode<PointSpring>(thread, node, stiffness_n_per_mm);
}

// det[a1 - a0, b0 - a0, b1 - a0]
inline double Coplanarity(const Vec3& a0, const Vec3& a1, const Vec3& b0, const Vec3& b1) {
  return (a1 - a0).dot((b0 - a0).cross(b1 - a0));
}

// At a coplanar instant: do the segments intersect? Solves a0 + s da = b0 + t db in least
// squares and accepts s, t in [0, 1] with a small residual. Independent of the solver's code.
inline bool SegmentsIntersectCoplanar(const Vec3& a0, const Vec3& a1, const Vec3& b0,
                                      const Vec3& b1, double tol) {
  const Vec3 da = a1 - a0, db = b1 - b0;
  Eigen::Matrix<double, 3, 2> A;
  A.col(0) = da;
  A.col(1) = -db;
  const Eigen::Vector2d st = A.colPivHouseholderQr().solve(b0 - a0);
  if (st.x() < -1e-9 || st.x() > 1 + 1e-9 || st.y() < -1e-9 || st.y() > 1 + 1e-9) return false;
  return (a0 + st.x() * da - (b0 + st.y() * db)).norm() < tol;
}

/// True if segments (a0,a1) and (b0,b1), moving linearly from *_s to *_e, pass through each
/// other: sign changes of the coplanarity determinant on a fine time grid, each refined by
/// bisection and checked for an actual intersection.
inline bool PassThrough(const Vec3& a0s, const Vec3& a1s, const Vec3& b0s, const Vec3& b1s,
                        const Vec3& a0e, const Vec3& a1e, const Vec3& b0e, const Vec3& b1e,
                        int samples = 32) {
  auto at = [&](double t, Vec3* a0, Vec3* a1, Vec3* b0, Vec3* b1) {
    *a0 = a0s + t * (a0e - a0s);
    *a1 = a1s + t * (a1e - a1s);
    *b0 = b0s + t * (b0e - b0s);
    *b1 = b1s + t * (b1e - b1s);
    return Coplanarity(*a0, *a1, *b0, *b1);
  };
  Vec3 a0, a1, b0, b1;
  double prev = at(0, &a0, &a1, &b0, &b1);
  for (int k = 1; k <= samples; ++k) {
    double lo = static_cast<double>(k - 1) / samples, hi = static_cast<double>(k) / samples;
    const double cur = at(hi, &a0, &a1, &b0, &b1);
    if ((prev < 0 && cur > 0) || (prev > 0 && cur < 0)) {
      double flo = prev;
      for (int it = 0; it < 60; ++it) {
        const double mid = 0.5 * (lo + hi);
        const double fm = at(mid, &a0, &a1, &b0, &b1);
        if ((fm < 0) == (flo < 0)) {
          lo = mid;
          flo = fm;
        } else {
          hi = mid;
        }
      }
      at(0.5 * (lo + hi), &a0, &a1, &b0, &b1);
      if (SegmentsIntersectCoplanar(a0, a1, b0, b1, 1e-6)) return true;
    }
    prev = cur;
  }
  return false;
}

}  // namespace arthrosim::physics::testing
