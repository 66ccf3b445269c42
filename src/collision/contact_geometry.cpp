// Geometric tests of the collision stage: nearest triangle with pseudo-normal, sweeps.
#include <algorithm>
#include <cmath>

#include "contact_internal.h"

namespace arthrosim::collision::internal {

void FillPositions(const Points& x, const std::vector<std::int32_t>& ids, std::vector<Vec3>* out) {
  out->resize(ids.size());
  for (std::size_t i = 0; i < ids.size(); ++i) (*out)[i] = x.col(ids[i]);
}

Vec3 VertexNormal(const Surface& s, const std::vector<Vec3>& p, std::int32_t v) {
  Vec3 n = Vec3::Zero();
  for (std::int32_t k = s.vertex_tri_start[v]; k < s.vertex_tri_start[v + 1]; ++k) {
    const mesh::Tri& t = s.local_tris[s.vertex_tris[k]];
    n += (p[t[1]] - p[t[0]]).cross(p[t[2]] - p[t[0]]);  // area weighted
  }
  return SafeNormalized(n, Vec3::UnitZ());
}

// The nearest triangle among the candidates, as if each were tested in ascending order (the
// first of exactly equal minima wins), and the pseudo-normal summed over the ties in ascending
// order. The candidate with the nearest box is tested first; then a candidate whose box is
// clearly farther than the best so far is skipped: it can be neither the minimum nor a tie, so
// the result is the same as testing them all. `qbox` bounds the query, `bvh` holds the
// triangles' boxes. `hint` (e.g. last step's nearest triangle), if among the candidates, is
// tested first instead: the order of the tests never changes the result (every minimum or tie
// is tested whatever the order, and equal minima go to the lowest index), a good first guess
// only lets more candidates be skipped.
Nearest NearestOnSurface(const Simplex& q, const Box& qbox, const std::vector<std::int32_t>& cand,
                         const TriangleBvh& bvh, const std::vector<Vec3>& p,
                         const std::vector<mesh::Tri>& tris, ContactTaskScratch* scratch,
                         std::int32_t hint) {
  Nearest best;
  const std::size_t n = cand.size();
  if (n == 0) return best;
  // Scratch on the stack for the usual handful of candidates.
  constexpr std::size_t kSmall = 64;
  double small_box[kSmall], small_d2[kSmall];
  double* box_d2 = small_box;
  double* d2 = small_d2;
  if (n > kSmall) {
    scratch->box_d2.resize(n);
    scratch->tri_d2.resize(n);
    box_d2 = scratch->box_d2.data();
    d2 = scratch->tri_d2.data();
  }
  std::fill(d2, d2 + n, -1.0);
  std::size_t first = 0;
  bool hinted = false;
  for (std::size_t i = 0; i < n; ++i) {
    box_d2[i] = BoxDist2(qbox, bvh.TriangleBox(cand[i]));
    if (cand[i] == hint) {
      first = i;
      hinted = true;
    } else if (!hinted && box_d2[i] < box_d2[first]) {
      first = i;
    }
  }
  // Beyond the tie tolerance below, with a wide margin for rounding: cannot matter.
  auto beyond = [&](double lower2) { return lower2 > best.pair.dist2 * (1 + 1e-6) + 1e-12; };
  auto test = [&](std::size_t i) {
    const mesh::Tri& t = tris[cand[i]];
    ClosestPair c;
    if (q.n == 1) {
      c = PointTriangle(q.v[0], p[t[0]], p[t[1]], p[t[2]]);
    } else if (!ClosestUnless(q, LocalTriangle(p, t),
                              best.found ? std::sqrt(best.pair.dist2 * (1 + 1e-6) + 1e-12) : -1.0,
                              &c)) {
      return;  // provably beyond the tie tolerance, like a far box
    }
    d2[i] = c.dist2;
    if (!best.found || c.dist2 < best.pair.dist2 ||
        (c.dist2 == best.pair.dist2 && cand[i] < best.tri)) {
      best.found = true;
      best.tri = cand[i];
      best.pair = c;
    }
  };
  test(first);
  for (std::size_t i = 0; i < n; ++i) {
    if (i == first || beyond(box_d2[i])) continue;
    test(i);
  }
  best.dist = std::sqrt(best.pair.dist2);
  const double tie = best.pair.dist2 * (1 + 1e-9) + 1e-18;
  Vec3 sum = Vec3::Zero();
  for (std::size_t i = 0; i < n; ++i) {
    if (d2[i] >= 0 && d2[i] <= tie) sum += FaceNormal(p, tris[cand[i]]);
  }
  const double len = sum.norm();
  best.pseudo = len > kMinDirection ? Vec3(sum / len) : FaceNormal(p, tris[best.tri]);
  return best;
}

// Conservative: false only when a triangle's plane separates the other simplex from it by more
// than `reach` (then no point pair is within reach). Cheap next to an exact triangle test.
bool PlanesAllowReach(const Simplex& a, const Simplex& b, double reach) {
  auto separated = [reach](const Simplex& t, const Simplex& o) {
    if (t.n != 3) return false;
    const Vec3 n = (t.v[1] - t.v[0]).cross(t.v[2] - t.v[0]);
    const double len = n.norm();
    if (!(len > 0)) return false;
    const double lim = (reach + kCullSlack) * len;
    double lo = n.dot(o.v[0] - t.v[0]), hi = lo;
    for (int i = 1; i < o.n; ++i) {
      const double d = n.dot(o.v[i] - t.v[0]);
      lo = std::min(lo, d);
      hi = std::max(hi, d);
    }
    return lo > lim || hi < -lim;
  };
  return !separated(a, b) && !separated(b, a);
}

// First substep at which the target (whose box is target_box) comes within `reach` of the swept
// core, -1 if none; `last`, if given, is the caller's Closest(sw.sub.back(), target). Substeps
// whose core box is farther than reach from target_box, or whose plane separates them, cannot
// touch: skipped without an exact test.
int FirstTouch(const Sweep& sw, double reach, const Simplex& target, const Box& target_box,
               ClosestPair* at, const ClosestPair* last) {
  const double reach2 = reach * reach;
  const std::size_t n = sw.sub.size();
  for (std::size_t s = 0; s < n; ++s) {
    if (last != nullptr && s + 1 == n) {  // already computed by the caller
      if (!(last->dist2 < reach2)) return -1;
      *at = *last;
      return static_cast<int>(s);
    }
    if (!NearBoxes(sw.sub_box[s], reach + kCullSlack, target_box)) continue;
    if (!PlanesAllowReach(sw.sub[s], target, reach)) continue;
    ClosestPair c;
    if (!ClosestUnless(sw.sub[s], target, reach, &c)) continue;  // provably out of reach
    if (c.dist2 < reach2) {
      *at = c;
      return static_cast<int>(s);
    }
  }
  return -1;
}

// Conservative: false when no substep can bring the target within reach (cheap tests only).
bool MayTouch(const Sweep& sw, double reach, const Simplex& target, const Box& target_box) {
  for (std::size_t s = 0; s < sw.sub.size(); ++s) {
    if (NearBoxes(sw.sub_box[s], reach + kCullSlack, target_box) &&
        PlanesAllowReach(sw.sub[s], target, reach)) {
      return true;
    }
  }
  return false;
}

// Contact on a thread segment point with parameter u (0 = node a, 1 = node b).
PointContact ThreadPoint(int thread, std::int32_t a, std::int32_t b, double u) {
  PointContact c;
  c.target = PointContact::Target::kThread;
  c.index = thread;
  if (u <= 0) {
    c.nodes = {a, -1, -1, -1};
    c.weights = {1, 0, 0, 0};
  } else if (u >= 1) {
    c.nodes = {b, -1, -1, -1};
    c.weights = {1, 0, 0, 0};
  } else {
    c.nodes = {a, b, -1, -1};
    c.weights = {1 - u, u, 0, 0};
  }
  return c;
}

PointContact SoftTrianglePoint(int body, const mesh::Tri& tri, const std::array<double, 3>& w,
                               const Vec3& normal, double offset_mm, double stiffness_n_per_mm,
                               int obstacle_id) {
  PointContact c;
  c.target = PointContact::Target::kSoftBody;
  c.index = body;
  c.nodes = {tri[0], tri[1], tri[2], -1};
  c.weights = {w[0], w[1], w[2], 0};
  c.normal = normal;
  c.offset_mm = offset_mm;
  c.stiffness_n_per_mm = stiffness_n_per_mm;
  c.obstacle_id = obstacle_id;
  return c;
}

}  // namespace arthrosim::collision::internal
