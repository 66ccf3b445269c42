// Terms of the thread solver that couple nodes beyond a segment: point contacts and springs on
// thread points, segment-segment contact terms, and the broad phase of segment pairs.
#include <algorithm>
#include <stdexcept>
#include <string>

#include "thread_internal.h"

namespace arthrosim::physics::thread_internal {
namespace {

// Same-thread pairs: skipped without self collision, and when closer than exclusion_factor
// diameters along the rest arc (neighbours along the chain always touch).
bool PairExcluded(const System& s, const std::vector<ThreadModel>& models,
                  const std::vector<ThreadRest>& rest, double exclusion_factor, int a, int b) {
  const ThreadSegmentRef& sa = s.segments[a];
  const ThreadSegmentRef& sb = s.segments[b];
  if (sa.thread != sb.thread) return false;
  if (!models[sa.thread].self_collision) return true;
  const int i = std::min(sa.seg, sb.seg), j = std::max(sa.seg, sb.seg);
  if (j - i < 2) return true;
  const double gap = rest[sa.thread].arc_mm[j] - rest[sa.thread].arc_mm[i + 1];
  return gap < exclusion_factor * models[sa.thread].diameter_mm;
}

}  // namespace

// Fills a point term from (thread, nodes, weights); false if it touches a dead node.
bool PointTerm(const System& s, int thread, const std::array<std::int32_t, 4>& nodes,
               const std::array<double, 4>& weights, int thread_nodes, Term* t) {
  t->count = 0;
  for (int k = 0; k < 4; ++k) {
    if (nodes[k] < 0 || weights[k] == 0) continue;
    if (nodes[k] >= thread_nodes)
      throw std::invalid_argument("thread contact/spring node " + std::to_string(nodes[k]) +
                                  " out of range");
    const int g = s.offset[thread] + nodes[k];
    if (!s.alive[g]) return false;
    t->node[t->count] = g;
    t->w[t->count] = weights[k];
    ++t->count;
  }
  return t->count > 0;
}

// Contact term for segments a, b from their closest points cp; a0..b1 are the end points the
// closest points were computed on (used only for the normal of touching segments).
Term SegmentPairTerm(const System& s, int a, int b, double stiffness, const SegmentClosest& cp,
                     const Vec3& a0, const Vec3& a1, const Vec3& b0, const Vec3& b1) {
  const ThreadSegmentRef& sa = s.segments[a];
  const ThreadSegmentRef& sb = s.segments[b];
  Term t;
  t.kind = Term::Kind::kPlane;
  t.count = 4;
  t.node = {sa.n0, sa.n1, sb.n0, sb.n1};
  t.w = {1 - cp.s, cp.s, -(1 - cp.t), -cp.t};
  t.k = stiffness;
  Vec3 n = cp.p - cp.q;
  const double len = n.norm();
  if (len > 1e-12) {
    n /= len;
  } else {
    // Touching exactly: separate along the common perpendicular (or any perpendicular).
    const Vec3 da = a1 - a0, db = b1 - b0;
    n = da.cross(db);
    if (n.norm() < 1e-12) n = da.unitOrthogonal();
    n.normalize();
  }
  t.vec = n;
  t.scalar = 0.5 * (s.seg_diameter[a] + s.seg_diameter[b]);
  return t;
}

SweptSegments Swept(const System& s, int a, int b, const Points& x1) {
  const ThreadSegmentRef& sa = s.segments[a];
  const ThreadSegmentRef& sb = s.segments[b];
  return SweptSegments{s.x0.col(sa.n0), s.x0.col(sa.n1), s.x0.col(sb.n0), s.x0.col(sb.n1),
                       x1.col(sa.n0),   x1.col(sa.n1),   x1.col(sb.n0),   x1.col(sb.n1)};
}

// Segment pairs whose swept boxes (x0 -> x1, grown by pad_factor * radius) overlap and that are
// not excluded, into s->kept (sorted).
void CandidatePairs(System* s, const std::vector<ThreadModel>& models,
                    const std::vector<ThreadRest>& rest, const ThreadSolverParams& p,
                    const Points& x1, double pad_factor) {
  s->boxes.resize(s->segments.size());
  for (std::size_t i = 0; i < s->segments.size(); ++i) {
    const ThreadSegmentRef& sg = s->segments[i];
    s->boxes[i] = SweptSegmentBox(s->x0.col(sg.n0), s->x0.col(sg.n1), x1.col(sg.n0), x1.col(sg.n1),
                                  0.5 * s->seg_diameter[i] * pad_factor);
  }
  OverlappingPairs(s->boxes, &s->order, &s->pairs);
  s->kept.clear();
  for (const auto& pr : s->pairs)
    if (!PairExcluded(*s, models, rest, p.exclusion_factor, pr[0], pr[1])) s->kept.push_back(pr);
}

}  // namespace arthrosim::physics::thread_internal
