// Knot identification on synthetic thread geometries: unknotted limbs, overhand (half hitch),
// granny and square knots, and invariance under thousands of seeded random rotations.
#include "arthrosim/instruments/knot_identify.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <sstream>

#include "arthrosim/core/rng.h"
#include "seated_knot_fixtures.h"

namespace arthrosim::instruments {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr int kTrefoilNodes = 96;
constexpr double kScaleMm = 4.0;

// A closed trefoil (left- or right-handed), kTrefoilNodes points, centre `at`, mm.
std::vector<Vec3> Trefoil(const Vec3& at, bool mirror) {
  std::vector<Vec3> p;
  for (int k = 0; k < kTrefoilNodes; ++k) {
    const double t = 2 * kPi * k / kTrefoilNodes;
    const double z = -std::sin(3 * t);
    p.push_back(at + kScaleMm * Vec3(std::sin(t) + 2 * std::sin(2 * t),
                                     std::cos(t) - 2 * std::cos(2 * t), mirror ? -z : z));
  }
  return p;
}

int ExtremeX(const std::vector<Vec3>& p, bool largest) {
  int best = 0;
  for (int k = 1; k < static_cast<int>(p.size()); ++k)
    if (largest ? p[k].x() > p[best].x() : p[k].x() < p[best].x()) best = k;
  return best;
}

// The closed curve opened at node `cut`: starts just after it, ends at it.
std::vector<Vec3> OpenAt(const std::vector<Vec3>& closed, int cut) {
  std::vector<Vec3> open;
  const int n = static_cast<int>(closed.size());
  for (int k = 1; k <= n; ++k) open.push_back(closed[(cut + k) % n]);
  return open;
}

// Nodes of a closed curve from index first to last (inclusive, cyclic).
std::vector<Vec3> Arc(const std::vector<Vec3>& closed, int first, int last) {
  std::vector<Vec3> out;
  const int n = static_cast<int>(closed.size());
  for (int k = first;; k = (k + 1) % n) {
    out.push_back(closed[k]);
    if (k == last) break;
  }
  return out;
}

// An overhand knot in one open strand: a trefoil opened at its outermost point.
std::vector<Vec3> Overhand(bool mirror) {
  const std::vector<Vec3> t = Trefoil(Vec3::Zero(), mirror);
  return OpenAt(t, ExtremeX(t, true));
}

// Two half hitches in a row (connected sum of two trefoils joined by a band), opened at the
// far end of the first: same handedness = granny, opposite = square.
std::vector<Vec3> TwoHitches(bool second_mirrored) {
  const int n = kTrefoilNodes, gap = 4;
  const std::vector<Vec3> t1 = Trefoil(Vec3::Zero(), false);
  const std::vector<Vec3> t2 = Trefoil(Vec3(7 * kScaleMm, 0, 0), second_mirrored);
  const int k1 = ExtremeX(t1, true), k2 = ExtremeX(t2, false);
  // t1 without its window at +x, t2 without its window at -x, joined so the bridges are short.
  std::vector<Vec3> curve = Arc(t1, (k1 + gap) % n, (k1 - gap + n) % n);
  std::vector<Vec3> second = Arc(t2, (k2 + gap) % n, (k2 - gap + n) % n);
  if ((curve.back() - second.back()).norm() < (curve.back() - second.front()).norm())
    std::reverse(second.begin(), second.end());
  curve.insert(curve.end(), second.begin(), second.end());
  return OpenAt(curve, ExtremeX(curve, false));
}

// Two limbs starting at the tissue (z = 0) that wind around each other `turns` times going up:
// crossings in every projection, no knot.
void TwistedLimbs(double turns, std::vector<Vec3>* a, std::vector<Vec3>* b) {
  a->clear();
  b->clear();
  for (int k = 0; k <= 60; ++k) {
    const double s = k / 60.0, angle = 2 * kPi * turns * s;
    const Vec3 r(1.5 * std::cos(angle), 1.5 * std::sin(angle), 25 * s);
    a->push_back(r);
    b->push_back(Vec3(-r.x(), -r.y(), r.z()));
  }
}

Quat RandomRotation(std::uint64_t* rng) {
  // Uniform on SO(3) (Shoemake's subgroup algorithm).
  const double u1 = NextUniform(rng), u2 = NextUniform(rng), u3 = NextUniform(rng);
  const double a = std::sqrt(1 - u1), b = std::sqrt(u1);
  return Quat(a * std::sin(2 * kPi * u2), a * std::cos(2 * kPi * u2), b * std::sin(2 * kPi * u3),
              b * std::cos(2 * kPi * u3))
      .normalized();
}

std::vector<Vec3> Transformed(const std::vector<Vec3>& p, const Quat& q, const Vec3& shift) {
  std::vector<Vec3> out;
  for (const Vec3& x : p) out.push_back(q * x + shift);
  return out;
}

// Identifies the strand under `count` seeded random rotations (and shifts); every one must give
// `expected`. The first failure is printed as a reproducer.
void ExpectInvariant(const std::vector<Vec3>& strand, KnotType expected, int count,
                     std::uint64_t seed) {
  std::uint64_t rng = seed;
  int failures = 0;
  for (int k = 0; k < count; ++k) {
    const Quat q = RandomRotation(&rng);
    const Vec3 shift(100 * NextUniform(&rng) - 50, 100 * NextUniform(&rng) - 50,
                     100 * NextUniform(&rng) - 50);
    const KnotIdentification id = IdentifyKnot(Transformed(strand, q, shift));
    if (id.type != expected) {
      if (failures == 0) {
        std::ostringstream s;
        s.precision(17);
        s << "rotation " << k << " (seed " << seed << "): quaternion w x y z = " << q.w() << " "
          << q.x() << " " << q.y() << " " << q.z() << ", shift = " << shift.transpose() << " gave "
          << KnotTypeName(id.type) << " (" << id.votes << "/" << id.projections << " votes, "
          << id.crossings << " crossings, writhe " << id.writhe << "), expected "
          << KnotTypeName(expected);
        ADD_FAILURE() << s.str();
      }
      ++failures;
    }
  }
  EXPECT_EQ(failures, 0) << "of " << count << " rotations";
}

TEST(KnotIdentify, ReidemeisterOneRemovesAKink) {
  std::vector<GaussEntry> code = {{0, true, 1}, {0, false, 1}};
  ReduceGaussCode(&code);
  EXPECT_TRUE(code.empty());
}

TEST(KnotIdentify, ReidemeisterTwoRemovesAnOverpassOnlyForOppositeSigns) {
  // Strand passes over crossings 0 and 1, later under 1 and 0: a removable overpass.
  std::vector<GaussEntry> bigon = {{0, true, 1}, {1, true, -1}, {1, false, -1}, {0, false, 1}};
  ReduceGaussCode(&bigon);
  EXPECT_TRUE(bigon.empty());
  // The same passages with equal signs are a clasp, not an overpass: they stay.
  std::vector<GaussEntry> clasp = {{0, true, 1}, {1, true, 1}, {0, false, 1}, {1, false, 1}};
  ReduceGaussCode(&clasp);
  EXPECT_EQ(clasp.size(), 4u);
}

TEST(KnotIdentify, NugatoryCrossingIsRemoved) {
  // Crossing 9's loop holds a whole trefoil (0, 1, 2, each passed twice inside it) and meets the
  // rest of the curve nowhere: 9 untwists, though its passages are not adjacent; 3 is a kink.
  std::vector<GaussEntry> code = {{9, true, 1},  {0, true, 1},  {1, false, 1}, {2, true, 1},
                                  {0, false, 1}, {1, true, 1},  {2, false, 1}, {9, false, 1},
                                  {3, true, -1}, {3, false, -1}};
  ReduceGaussCode(&code);
  ASSERT_EQ(code.size(), 6u);
  for (const GaussEntry& e : code) EXPECT_LE(e.crossing, 2);
}

TEST(KnotIdentify, TrefoilCodeIsIrreducible) {
  std::vector<GaussEntry> code = {{0, true, 1},  {1, false, 1}, {2, true, 1},
                                  {0, false, 1}, {1, true, 1},  {2, false, 1}};
  ReduceGaussCode(&code);
  EXPECT_EQ(code.size(), 6u);
}

// The knot determinant of standard diagrams (Rolfsen's table): unknot 1 (a diagram of two
// crossings that move II removes, and a one-crossing kink), trefoil 3, figure-eight 5, granny
// (a trefoil followed by a trefoil) 9; a code that is not a diagram gives -1.
TEST(KnotIdentify, KnotDeterminantOfStandardDiagrams) {
  const std::vector<GaussEntry> trefoil = {{0, true, 1},  {1, false, 1}, {2, true, 1},
                                           {0, false, 1}, {1, true, 1},  {2, false, 1}};
  EXPECT_EQ(KnotDeterminant(trefoil), 3);
  const std::vector<GaussEntry> figure_eight = {{0, true, 1},   {1, false, 1}, {2, true, -1},
                                                {3, false, -1}, {1, true, 1},  {0, false, 1},
                                                {3, true, -1},  {2, false, -1}};
  EXPECT_EQ(KnotDeterminant(figure_eight), 5);
  std::vector<GaussEntry> granny = trefoil;
  for (const GaussEntry& e : trefoil) granny.push_back({e.crossing + 3, e.over, e.sign});
  EXPECT_EQ(KnotDeterminant(granny), 9);
  const std::vector<GaussEntry> bigon = {
      {0, true, 1}, {1, true, -1}, {1, false, -1}, {0, false, 1}};
  EXPECT_EQ(KnotDeterminant(bigon), 1);
  EXPECT_EQ(KnotDeterminant({{0, true, 1}, {0, false, 1}}), 1);
  EXPECT_EQ(KnotDeterminant({}), 1);
  EXPECT_EQ(KnotDeterminant({{0, true, 1}, {1, true, 1}, {0, true, 1}, {1, false, 1}}), -1);
  // At the limit its 128-bit bound is proved for: 16 trefoils in a row (48 crossings) give
  // 3^16, exactly; 17 (51 crossings) are not computed.
  std::vector<GaussEntry> chain;
  for (int k = 0; k < 17; ++k) {
    for (const GaussEntry& e : trefoil) chain.push_back({e.crossing + 3 * k, e.over, e.sign});
    if (k == 15) {
      EXPECT_EQ(KnotDeterminant(chain), 43046721);
    }
  }
  EXPECT_EQ(KnotDeterminant(chain), -1);
}

// A seated half hitch whose tails run down to a portal beside each other: moves I and II cannot
// reduce several of its projections to three crossings (IdentifyKnot said `unknown`, 8 of 13,
// before the determinant classified such diagrams), but every projection's determinant is 3.
TEST(KnotIdentify, SeatedHalfHitchWithTangledTailsIsAHalfHitch) {
  const KnotIdentification id =
      IdentifyKnot(testing::kSeatedTrefoilLimbA, testing::kSeatedTrefoilLimbB);
  EXPECT_EQ(id.type, KnotType::kHalfHitch) << KnotTypeName(id.type) << " " << id.votes;
  EXPECT_EQ(id.half_hitches, 1);
  EXPECT_EQ(id.votes, 13);
}

// The determinant is not a licence to call a tangle a half hitch: limbs whose diagrams all have
// determinant 7 (no throw of the pusher makes that knot) stay unknown.
TEST(KnotIdentify, AKnotOfDeterminantSevenIsNotAHalfHitch) {
  const KnotIdentification id =
      IdentifyKnot(testing::kSeatedDeterminant7LimbA, testing::kSeatedDeterminant7LimbB);
  EXPECT_EQ(id.type, KnotType::kUnknown) << KnotTypeName(id.type);
}

TEST(KnotIdentify, ClosureStaysOutsideTheNodes) {
  const std::vector<Vec3> strand = Overhand(false);
  const std::vector<Vec3> closed = CloseStrand(strand);
  ASSERT_GT(closed.size(), strand.size());
  Vec3 c = Vec3::Zero();
  for (const Vec3& p : strand) c += p;
  c /= static_cast<double>(strand.size());
  double reach = 0;
  for (const Vec3& p : strand) reach = std::max(reach, (p - c).norm());
  for (std::size_t k = strand.size(); k < closed.size(); ++k)
    EXPECT_NEAR((closed[k] - c).norm(), 3 * reach, 1e-9 * reach);
}

TEST(KnotIdentify, UnknottedLimbsCrossingTwiceAreNone) {
  std::vector<Vec3> a, b;
  TwistedLimbs(1.5, &a, &b);
  // Seen from the side the limbs cross twice: the raw code has crossings, the reduced none.
  std::vector<Vec3> strand(a.rbegin(), a.rend());
  strand.insert(strand.end(), b.begin(), b.end());
  const std::vector<GaussEntry> raw = GaussCode(CloseStrand(strand), Vec3::UnitX());
  EXPECT_GE(raw.size(), 4u);
  const KnotIdentification id = IdentifyKnot(a, b);
  EXPECT_EQ(id.type, KnotType::kNone);
  EXPECT_EQ(id.crossings, 0);
}

TEST(KnotIdentify, OverhandIsAHalfHitchOfEitherHandedness) {
  for (bool mirror : {false, true}) {
    const KnotIdentification id = IdentifyKnot(Overhand(mirror));
    EXPECT_EQ(id.type, KnotType::kHalfHitch) << "mirror " << mirror;
    EXPECT_EQ(id.crossings, 3);
    EXPECT_EQ(std::abs(id.writhe), 3);
    EXPECT_EQ(id.half_hitches, 1);
    EXPECT_GT(id.votes, id.projections / 2);
  }
  EXPECT_EQ(-IdentifyKnot(Overhand(false)).writhe, IdentifyKnot(Overhand(true)).writhe);
}

TEST(KnotIdentify, OverhandTiedWithTwoLimbs) {
  // The same knot split at its middle into two limbs that start at the tissue.
  const std::vector<Vec3> strand = Overhand(false);
  const std::size_t mid = strand.size() / 2;
  std::vector<Vec3> a(strand.begin(), strand.begin() + static_cast<std::ptrdiff_t>(mid));
  std::reverse(a.begin(), a.end());
  const std::vector<Vec3> b(strand.begin() + static_cast<std::ptrdiff_t>(mid), strand.end());
  EXPECT_EQ(IdentifyKnot(a, b).type, KnotType::kHalfHitch);
}

TEST(KnotIdentify, GrannyAndSquareAreTwoHalfHitches) {
  const KnotIdentification granny = IdentifyKnot(TwoHitches(false));
  EXPECT_EQ(granny.type, KnotType::kGranny);
  EXPECT_EQ(granny.crossings, 6);
  EXPECT_EQ(std::abs(granny.writhe), 6);
  EXPECT_EQ(granny.half_hitches, 2);
  const KnotIdentification square = IdentifyKnot(TwoHitches(true));
  EXPECT_EQ(square.type, KnotType::kSquare);
  EXPECT_EQ(square.crossings, 6);
  EXPECT_EQ(square.writhe, 0);
  EXPECT_EQ(square.half_hitches, 2);
}

TEST(KnotIdentify, InvariantUnderRandomRotations) {
  std::vector<Vec3> a, b;
  TwistedLimbs(1.5, &a, &b);
  std::vector<Vec3> twisted(a.rbegin(), a.rend());
  twisted.insert(twisted.end(), b.begin(), b.end());
  ExpectInvariant(twisted, KnotType::kNone, 2000, 11);
  ExpectInvariant(Overhand(false), KnotType::kHalfHitch, 2000, 12);
  ExpectInvariant(Overhand(true), KnotType::kHalfHitch, 2000, 13);
  ExpectInvariant(TwoHitches(false), KnotType::kGranny, 2000, 14);
  ExpectInvariant(TwoHitches(true), KnotType::kSquare, 2000, 15);
}

TEST(KnotIdentify, RejectsTooShortOrNonFiniteStrands) {
  EXPECT_THROW(IdentifyKnot(std::vector<Vec3>{Vec3::Zero()}), std::invalid_argument);
  EXPECT_THROW(IdentifyKnot(std::vector<Vec3>{Vec3::Zero(), Vec3(NAN, 0, 0)}),
               std::invalid_argument);
}

}  // namespace
}  // namespace arthrosim::instruments
