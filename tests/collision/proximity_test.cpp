// Exact closest points against brute-force sampling on random cases.
#include "arthrosim/collision/proximity.h"

#include <gtest/gtest.h>

#include <cmath>

#include "arthrosim/core/rng.h"

namespace arthrosim::collision {
namespace {

struct Random {
  std::uint64_t s;
  double U() { return NextUniform(&s); }
  Vec3 Point(double scale = 1.0) { return scale * Vec3(2 * U() - 1, 2 * U() - 1, 2 * U() - 1); }
};

// Samples of a simplex on a barycentric grid with m intervals per edge.
std::vector<Vec3> Samples(const Simplex& s, int m) {
  std::vector<Vec3> out;
  if (s.n == 1) return {s.v[0]};
  for (int i = 0; i <= m; ++i) {
    if (s.n == 2) {
      const double t = static_cast<double>(i) / m;
      out.push_back((1 - t) * s.v[0] + t * s.v[1]);
      continue;
    }
    for (int j = 0; i + j <= m; ++j) {
      const double a = static_cast<double>(i) / m, b = static_cast<double>(j) / m;
      out.push_back((1 - a - b) * s.v[0] + a * s.v[1] + b * s.v[2]);
    }
  }
  return out;
}

double MaxEdge(const Simplex& s) {
  double e = 0;
  for (int i = 0; i < s.n; ++i)
    for (int j = i + 1; j < s.n; ++j) e = std::max(e, (s.v[i] - s.v[j]).norm());
  return e;
}

// Checks the structural invariants of a result.
void ExpectValid(const ClosestPair& r, const Simplex& a, const Simplex& b) {
  for (const auto* w : {&r.wa, &r.wb}) {
    EXPECT_GE((*w)[0], -1e-12);
    EXPECT_GE((*w)[1], -1e-12);
    EXPECT_GE((*w)[2], -1e-12);
  }
  EXPECT_NEAR(r.wa[0] + r.wa[1] + r.wa[2], 1.0, 1e-12);
  EXPECT_NEAR(r.wb[0] + r.wb[1] + r.wb[2], 1.0, 1e-12);
  for (int i = a.n; i < 3; ++i) EXPECT_EQ(r.wa[i], 0.0);
  for (int i = b.n; i < 3; ++i) EXPECT_EQ(r.wb[i], 0.0);
  EXPECT_LT((r.pa - a.At(r.wa)).norm(), 1e-12);
  EXPECT_LT((r.pb - b.At(r.wb)).norm(), 1e-12);
  EXPECT_NEAR(std::sqrt(r.dist2), (r.pa - r.pb).norm(), 1e-12);
}

Simplex RandomSimplex(Random* rnd, int n) {
  Simplex s;
  s.n = n;
  for (int i = 0; i < n; ++i) s.v[i] = rnd->Point();
  return s;
}

TEST(Proximity, PointTriangleMatchesSampling) {
  Random rnd{11};
  const int m = 200;
  for (int c = 0; c < 150; ++c) {
    const Simplex tri = RandomSimplex(&rnd, 3);
    const Vec3 p = rnd.Point(1.5);
    const ClosestPair r = PointTriangle(p, tri.v[0], tri.v[1], tri.v[2]);
    ExpectValid(r, PointSimplex(p), tri);
    double brute = 1e300;
    for (const Vec3& q : Samples(tri, m)) brute = std::min(brute, (q - p).norm());
    const double exact = std::sqrt(r.dist2);
    EXPECT_LE(exact, brute + 1e-12) << "case " << c;
    EXPECT_LE(brute, exact + MaxEdge(tri) / m) << "case " << c;
  }
}

TEST(Proximity, PointSegmentMatchesSampling) {
  Random rnd{12};
  for (int c = 0; c < 300; ++c) {
    const Simplex seg = RandomSimplex(&rnd, 2);
    const Vec3 p = rnd.Point(1.5);
    const ClosestPair r = PointSegment(p, seg.v[0], seg.v[1]);
    ExpectValid(r, PointSimplex(p), seg);
    double brute = 1e300;
    for (const Vec3& q : Samples(seg, 2000)) brute = std::min(brute, (q - p).norm());
    EXPECT_LE(std::sqrt(r.dist2), brute + 1e-12);
    EXPECT_LE(brute, std::sqrt(r.dist2) + MaxEdge(seg) / 2000);
  }
}

// Pairs of simplices: brute force = min over samples of A of the (verified) exact point query
// on B, and the symmetric one.
double BruteDistance(const Simplex& a, const Simplex& b, int m) {
  double best = 1e300;
  for (const Vec3& p : Samples(a, m)) {
    best = std::min(best, std::sqrt(Closest(PointSimplex(p), b).dist2));
  }
  for (const Vec3& p : Samples(b, m)) {
    best = std::min(best, std::sqrt(Closest(PointSimplex(p), a).dist2));
  }
  return best;
}

void CheckPairs(int na, int nb, std::uint64_t seed, int cases, int m) {
  Random rnd{seed};
  for (int c = 0; c < cases; ++c) {
    Simplex a = RandomSimplex(&rnd, na), b = RandomSimplex(&rnd, nb);
    if (c % 5 == 1) {  // near-parallel / coplanar configurations
      for (int i = 0; i < b.n; ++i)
        b.v[i] = a.v[i % a.n] + Vec3(0.3, 0.1, 0.0) + 1e-9 * rnd.Point();
    }
    const ClosestPair r = Closest(a, b);
    ExpectValid(r, a, b);
    const double exact = std::sqrt(r.dist2);
    const double brute = BruteDistance(a, b, m);
    // Near-parallel cases (perturbed by 1e-9) have a distance that varies by ~1e-9 along the
    // overlap; any point of that flat valley is an acceptable answer.
    const double flat = c % 5 == 1 ? 1e-8 : 1e-12;
    EXPECT_LE(exact, brute + flat) << na << "-" << nb << " case " << c << " diff " << exact - brute;
    EXPECT_LE(brute, exact + (MaxEdge(a) + MaxEdge(b)) / m) << na << "-" << nb << " case " << c;
    // Swapping the arguments gives the same distance.
    EXPECT_NEAR(std::sqrt(Closest(b, a).dist2), exact, 1e-12);
  }
}

TEST(Proximity, SegmentSegmentMatchesSampling) { CheckPairs(2, 2, 21, 300, 400); }
TEST(Proximity, SegmentTriangleMatchesSampling) { CheckPairs(2, 3, 22, 200, 120); }
TEST(Proximity, TriangleTriangleMatchesSampling) { CheckPairs(3, 3, 23, 150, 60); }

// The segment-triangle and triangle-triangle tests skip feature pairs that a cheap plane or
// side-plane bound proves no nearer than the best so far. Oracle: the same features evaluated
// in full, in the same order with the same strict improvement. Skipping must never change the
// result, bit for bit. Cases: random, and near-surface ones (a segment or triangle hovering
// 0-0.5 over a triangle of a flat fan, 0-3 beside it), where the bounds skip most.
ClosestPair Remapped(const ClosestPair& q, int ia0, int ia1, int ib0, int ib1, bool a_edge,
                     bool b_edge) {
  ClosestPair r = q;
  if (a_edge) {
    r.wa = {0, 0, 0};
    r.wa[ia0] = q.wa[0];
    r.wa[ia1] += q.wa[1];
  }
  if (b_edge) {
    r.wb = {0, 0, 0};
    r.wb[ib0] = q.wb[0];
    r.wb[ib1] += q.wb[1];
  }
  return r;
}

// Full evaluation for a non-intersecting pair (a: segment or triangle, b: triangle).
ClosestPair FullEvaluation(const Simplex& a, const Simplex& b) {
  const int edges[3][2] = {{0, 1}, {1, 2}, {2, 0}};
  ClosestPair best;
  best.dist2 = -1;
  auto take = [&](const ClosestPair& q) {
    if (best.dist2 < 0 || q.dist2 < best.dist2) best = q;
  };
  for (int i = 0; i < a.n; ++i) {
    ClosestPair q = PointTriangle(a.v[i], b.v[0], b.v[1], b.v[2]);
    q.wa = {0, 0, 0};
    q.wa[i] = 1;
    take(q);
  }
  if (a.n == 3) {
    for (int i = 0; i < 3; ++i) {
      const ClosestPair p = PointTriangle(b.v[i], a.v[0], a.v[1], a.v[2]);
      ClosestPair q = p;
      q.wa = p.wb;
      q.wb = {0, 0, 0};
      q.wb[i] = 1;
      take(q);
    }
  }
  const int na_edges = a.n == 3 ? 3 : 1;
  for (int ka = 0; ka < na_edges; ++ka) {
    const int* ea = a.n == 3 ? edges[ka] : edges[0];
    for (const auto& eb : edges) {
      take(Remapped(SegmentSegment(a.v[ea[0]], a.v[ea[1]], b.v[eb[0]], b.v[eb[1]]), ea[0], ea[1],
                    eb[0], eb[1], a.n == 3, true));
    }
  }
  return best;
}

void CheckSkipsChangeNothing(int na, std::uint64_t seed, int cases) {
  Random rnd{seed};
  int compared = 0;
  for (int c = 0; c < cases; ++c) {
    Simplex b = RandomSimplex(&rnd, 3);
    Simplex a = RandomSimplex(&rnd, na);
    if (c % 2 == 1) {  // near a flat fan triangle
      b = TriangleSimplex(Vec3(0, 0, 0), Vec3(1.5, 0, 0), Vec3(0.4, 1.3, 0));
      const Vec3 off(3 * rnd.U() - 1, 3 * rnd.U() - 1, 0.5 * rnd.U());
      for (int i = 0; i < na; ++i) a.v[i] = off + Vec3(rnd.U(), rnd.U(), 0.2 * rnd.U());
    }
    const ClosestPair r = Closest(a, b);
    if (r.dist2 == 0) continue;  // intersecting: a crossing, not a feature minimum
    const ClosestPair f = FullEvaluation(a, b);
    ++compared;
    EXPECT_EQ(r.dist2, (a.At(f.wa) - b.At(f.wb)).squaredNorm()) << na << " case " << c;
    for (int k = 0; k < 3; ++k) {
      EXPECT_EQ(r.wa[k], f.wa[k]) << na << " case " << c;
      EXPECT_EQ(r.wb[k], f.wb[k]) << na << " case " << c;
    }
  }
  EXPECT_GT(compared, cases / 2);
}

TEST(Proximity, SegmentTriangleSkipsChangeNothing) { CheckSkipsChangeNothing(2, 31, 4000); }
TEST(Proximity, TriangleTriangleSkipsChangeNothing) { CheckSkipsChangeNothing(3, 32, 4000); }

// ClosestUnless either equals Closest bit for bit or declines only when the pair is farther
// than the limit; over near-surface cases it declines often (so a search saves tests).
TEST(Proximity, ClosestUnlessDeclinesOnlyBeyondTheLimit) {
  Random rnd{33};
  int declined = 0;
  const int cases = 4000;
  for (int c = 0; c < cases; ++c) {
    const Simplex tri = TriangleSimplex(Vec3(0, 0, 0), Vec3(1.5, 0, 0), Vec3(0.4, 1.3, 0));
    const Vec3 off(4 * rnd.U() - 1.5, 4 * rnd.U() - 1.5, 0.6 * rnd.U() - 0.1);
    const Simplex seg =
        SegmentSimplex(off, off + Vec3(rnd.U() - 0.5, rnd.U() - 0.5, 0.1 * rnd.U()));
    const double limit = 0.5 * rnd.U();
    const bool swap = c % 3 == 0;
    const Simplex& a = swap ? tri : seg;
    const Simplex& b = swap ? seg : tri;
    const ClosestPair full = Closest(a, b);
    ClosestPair r;
    if (!ClosestUnless(a, b, limit, &r)) {
      ++declined;
      EXPECT_GT(std::sqrt(full.dist2), limit) << "case " << c;
      continue;
    }
    EXPECT_EQ(r.dist2, full.dist2) << "case " << c;
    for (int k = 0; k < 3; ++k) {
      EXPECT_EQ(r.wa[k], full.wa[k]);
      EXPECT_EQ(r.wb[k], full.wb[k]);
    }
    ClosestPair never;
    ASSERT_TRUE(ClosestUnless(a, b, -1.0, &never));  // a negative limit never declines
    EXPECT_EQ(never.dist2, full.dist2);
  }
  std::printf("declined %d of %d\n", declined, cases);
  EXPECT_GT(declined, cases / 4);
}

TEST(Proximity, PiercingSegmentHasZeroDistanceAtTheCrossing) {
  const Vec3 a(0, 0, 0), b(4, 0, 0), c(0, 4, 0);
  const ClosestPair r = SegmentTriangle(Vec3(1, 1, -1), Vec3(1, 1, 3), a, b, c);
  EXPECT_EQ(r.dist2, 0.0);
  EXPECT_NEAR(r.wa[1], 0.25, 1e-15);
  EXPECT_LT((r.pb - Vec3(1, 1, 0)).norm(), 1e-14);
}

TEST(Proximity, DegenerateInputsStayFinite) {
  const Vec3 p(0.3, 0.2, 1.0);
  const ClosestPair r1 = PointTriangle(p, Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(2, 0, 0));  // needle
  EXPECT_NEAR(std::sqrt(r1.dist2), std::sqrt(0.04 + 1.0), 1e-14);
  const ClosestPair r2 = SegmentSegment(Vec3(0, 0, 0), Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(1, 0, 0));
  EXPECT_EQ(r2.dist2, 1.0);
  const ClosestPair r3 =
      SegmentTriangle(Vec3(0, 0, 1), Vec3(1, 0, 1), Vec3(0, 0, 0), Vec3(0, 0, 0), Vec3(0, 0, 0));
  EXPECT_EQ(r3.dist2, 1.0);
}

TEST(Proximity, RoundedGapIsCoreDistanceMinusRadius) {
  const double g = RoundedTriangleGap(PointSimplex(Vec3(0.5, 0.5, 3)), 2.0, Vec3(0, 0, 0),
                                      Vec3(4, 0, 0), Vec3(0, 4, 0));
  EXPECT_NEAR(g, 1.0, 1e-15);
  const double c = RoundedTriangleGap(SegmentSimplex(Vec3(-5, 1, 0.5), Vec3(5, 1, 0.5)), 1.0,
                                      Vec3(0, 0, 0), Vec3(4, 0, 0), Vec3(0, 4, 0));
  EXPECT_NEAR(c, -0.5, 1e-15);
}

}  // namespace
}  // namespace arthrosim::collision
