// Knot identification: closure, projected signed Gauss codes, Reidemeister reduction, vote.
#include "arthrosim/instruments/knot_identify.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <stdexcept>

#include "arthrosim/core/enum_names.h"

namespace arthrosim::instruments {
namespace {

constexpr int kClosureArcPoints = 16;  // chords stay within cos(pi/32) of the sphere radius
constexpr double kClosureRadiusScale = 3.0;
// Beyond this many crossings (after reduction) the determinant is not computed. Its exact
// elimination multiplies two minors of order up to n - 2 before each division; a colouring
// matrix row has norm <= sqrt(6), so by Hadamard's bound such a product is <= 6^(n - 2), within
// a signed 128-bit integer (2^127) for n <= 48 (6^46 < 2^119).
constexpr int kMaxDeterminantCrossings = 48;

// A unit vector perpendicular to u.
Vec3 AnyPerpendicular(const Vec3& u) {
  const Vec3 helper = std::abs(u.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitY();
  return u.cross(helper).normalized();
}

// Unit direction from the centroid to an end; the end's own segment direction if the end sits
// on the centroid.
Vec3 OutwardDirection(const Vec3& end, const Vec3& neighbour, const Vec3& centroid) {
  Vec3 u = end - centroid;
  if (u.norm() > 0) return u.normalized();
  u = end - neighbour;
  if (u.norm() > 0) return u.normalized();
  return Vec3::UnitX();
}

// Points on the sphere (centre c, radius r) from direction u0 to u1 (exclusive of both), along
// the great circle; through a perpendicular pole when the two are (nearly) opposite.
void AppendArc(const Vec3& c, double r, const Vec3& u0, const Vec3& u1, std::vector<Vec3>* out) {
  const double cos_angle = std::clamp(u0.dot(u1), -1.0, 1.0);
  if (cos_angle < -0.99) {
    const Vec3 pole = AnyPerpendicular(u0);
    AppendArc(c, r, u0, pole, out);
    out->push_back(c + r * pole);
    AppendArc(c, r, pole, u1, out);
    return;
  }
  const double angle = std::acos(cos_angle);
  if (angle < 1e-12) return;
  const Vec3 w = (u1 - cos_angle * u0).normalized();  // in-plane, perpendicular to u0
  for (int k = 1; k < kClosureArcPoints; ++k) {
    const double a = angle * k / kClosureArcPoints;
    out->push_back(c + r * (std::cos(a) * u0 + std::sin(a) * w));
  }
}

// The 13 projection directions in the strand's principal frame (eigenvectors of the node
// covariance): 3 axes, 6 face diagonals, 4 body diagonals.
std::array<Vec3, 13> ProjectionDirections(const std::vector<Vec3>& strand) {
  Vec3 centroid = Vec3::Zero();
  for (const Vec3& p : strand) centroid += p;
  centroid /= static_cast<double>(strand.size());
  Mat3 cov = Mat3::Zero();
  for (const Vec3& p : strand) cov += (p - centroid) * (p - centroid).transpose();
  const Eigen::SelfAdjointEigenSolver<Mat3> eig(cov);
  const Vec3 e0 = eig.eigenvectors().col(0), e1 = eig.eigenvectors().col(1),
             e2 = eig.eigenvectors().col(2);
  return {e0,
          e1,
          e2,
          (e0 + e1).normalized(),
          (e0 - e1).normalized(),
          (e0 + e2).normalized(),
          (e0 - e2).normalized(),
          (e1 + e2).normalized(),
          (e1 - e2).normalized(),
          (e0 + e1 + e2).normalized(),
          (e0 + e1 - e2).normalized(),
          (e0 - e1 + e2).normalized(),
          (e0 - e1 - e2).normalized()};
}

// A passage of the curve through a crossing, at curve parameter `at` (segment index + t).
struct Passage {
  double at = 0;
  GaussEntry entry;
};

double Cross2(const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  return a.x() * b.y() - a.y() * b.x();
}

// Classification of one reduced code.
KnotIdentification Classify(const std::vector<GaussEntry>& code) {
  KnotIdentification r;
  r.crossings = static_cast<int>(code.size() / 2);
  for (const GaussEntry& e : code)
    if (e.over) r.writhe += e.sign;
  if (r.crossings == 0) {
    r.type = KnotType::kNone;
  } else if (r.crossings == 3 && std::abs(r.writhe) == 3) {
    r.type = KnotType::kHalfHitch;
  } else if (r.crossings == 6 && std::abs(r.writhe) == 6) {
    r.type = KnotType::kGranny;
  } else if (r.crossings == 6 && r.writhe == 0) {
    r.type = KnotType::kSquare;
  } else if (r.crossings >= 9 && r.crossings % 3 == 0 && std::abs(r.writhe) % 3 == 0) {
    r.type = KnotType::kHalfHitches;
  } else {
    r.type = KnotType::kUnknown;
  }
  if (r.type == KnotType::kHalfHitch || r.type == KnotType::kGranny ||
      r.type == KnotType::kSquare || r.type == KnotType::kHalfHitches)
    r.half_hitches = r.crossings / 3;
  return r;
}

bool SameClass(const KnotIdentification& a, const KnotIdentification& b) {
  return a.type == b.type && a.half_hitches == b.half_hitches;
}

// The knot determinant (no Reidemeister move changes it) checks the class read off a reduced
// diagram and decides where the diagram does not: moves I and II cannot simplify every diagram
// (a tangle of the tails may need move III), and a diagram they leave with 6 or 9 crossings may
// be a half hitch all the same. A class is kept when its determinant agrees (none 1, a half hitch
// 3, two half hitches 9, k half hitches 3^k); otherwise determinant 1 is no knot, 3 a half hitch,
// and anything else (9 without a granny's or square's diagram: the determinant does not tell
// them apart; 5, 7, ...: knots no throw makes) unknown.
void ClassifyByDeterminant(const std::vector<GaussEntry>& code, KnotIdentification* r) {
  const std::int64_t det = KnotDeterminant(code);
  if (det < 0) return;  // too many crossings to compute: the diagram's class stands
  std::int64_t expected = 1;
  for (int h = 0; h < r->half_hitches; ++h) expected *= 3;
  if (r->type != KnotType::kUnknown && det == expected) return;
  if (det == 1) {
    r->type = KnotType::kNone;
    r->half_hitches = 0;
  } else if (det == 3) {
    r->type = KnotType::kHalfHitch;
    r->half_hitches = 1;
  } else {
    r->type = KnotType::kUnknown;
    r->half_hitches = 0;
  }
}

// True if the crossing passed at position k is nugatory: every other crossing passed between its
// two passages is passed there twice, so the loop from one passage to the other meets the rest
// of the curve nowhere and the crossing untwists (move I generalised).
bool Nugatory(const std::vector<GaussEntry>& code, int k) {
  const int m = static_cast<int>(code.size());
  int j = -1;
  for (int i = 0; i < m; ++i)
    if (i != k && code[i].crossing == code[k].crossing) j = i;
  if (j < 0) return false;
  const int lo = std::min(j, k), hi = std::max(j, k);
  for (int i = lo + 1; i < hi; ++i) {
    int inside = 0;
    for (int q = lo + 1; q < hi; ++q) inside += code[q].crossing == code[i].crossing ? 1 : 0;
    if (inside != 2) return false;
  }
  return true;
}

}  // namespace

const char* KnotTypeName(KnotType type) {
  static constexpr EnumName<KnotType> kNames[] = {{KnotType::kNone, "none"},
                                                  {KnotType::kHalfHitch, "half_hitch"},
                                                  {KnotType::kGranny, "granny"},
                                                  {KnotType::kSquare, "square"},
                                                  {KnotType::kHalfHitches, "half_hitches"},
                                                  {KnotType::kUnknown, "unknown"}};
  return NameIn(kNames, type, "unknown");
}

std::vector<Vec3> CloseStrand(const std::vector<Vec3>& strand) {
  if (strand.size() < 2)
    throw std::invalid_argument("knot identification needs a strand of at least 2 nodes, got " +
                                std::to_string(strand.size()));
  Vec3 centroid = Vec3::Zero();
  for (const Vec3& p : strand) {
    if (!p.allFinite())
      throw std::invalid_argument("knot identification: strand node is not finite");
    centroid += p;
  }
  centroid /= static_cast<double>(strand.size());
  double reach = 0;
  for (const Vec3& p : strand) reach = std::max(reach, (p - centroid).norm());
  const double radius = kClosureRadiusScale * std::max(reach, 1e-9);
  const Vec3 u_last = OutwardDirection(strand.back(), strand[strand.size() - 2], centroid);
  const Vec3 u_first = OutwardDirection(strand.front(), strand[1], centroid);
  std::vector<Vec3> closed = strand;
  closed.push_back(centroid + radius * u_last);
  AppendArc(centroid, radius, u_last, u_first, &closed);
  closed.push_back(centroid + radius * u_first);
  return closed;
}

std::vector<GaussEntry> GaussCode(const std::vector<Vec3>& closed, const Vec3& direction) {
  const Vec3 d = direction.normalized();
  const Vec3 e1 = AnyPerpendicular(d);
  const Vec3 e2 = d.cross(e1);
  const int n = static_cast<int>(closed.size());
  std::vector<Eigen::Vector2d> q(static_cast<std::size_t>(n));
  std::vector<double> h(static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i) {
    q[i] = Eigen::Vector2d(closed[i].dot(e1), closed[i].dot(e2));
    h[i] = closed[i].dot(d);
  }
  // Sweep over the segments sorted by their smallest first projected coordinate.
  std::vector<int> order(static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i) order[i] = i;
  const auto lo = [&](int i) { return std::min(q[i].x(), q[(i + 1) % n].x()); };
  const auto hi = [&](int i) { return std::max(q[i].x(), q[(i + 1) % n].x()); };
  std::sort(order.begin(), order.end(), [&](int a, int b) {
    const double la = lo(a), lb = lo(b);
    return la < lb || (la == lb && a < b);
  });
  std::vector<Passage> passages;
  int crossing = 0;
  for (int oi = 0; oi < n; ++oi) {
    const int i = order[oi];
    const double i_hi = hi(i);
    for (int oj = oi + 1; oj < n && lo(order[oj]) <= i_hi; ++oj) {
      int a = i, b = order[oj];
      if (a > b) std::swap(a, b);
      if (b == a + 1 || (a == 0 && b == n - 1)) continue;  // neighbours share a point
      const Eigen::Vector2d pa = q[a], ra = q[(a + 1) % n] - pa;
      const Eigen::Vector2d pb = q[b], rb = q[(b + 1) % n] - pb;
      const double denom = Cross2(ra, rb);
      if (denom == 0) continue;  // parallel in projection: no transversal crossing
      const double s = Cross2(pb - pa, rb) / denom;
      const double t = Cross2(pb - pa, ra) / denom;
      if (!(s >= 0 && s < 1 && t >= 0 && t < 1)) continue;  // half-open: a vertex counts once
      const double ha = h[a] + s * (h[(a + 1) % n] - h[a]);
      const double hb = h[b] + t * (h[(b + 1) % n] - h[b]);
      const bool a_over = ha > hb;
      const Vec3 ta = closed[(a + 1) % n] - closed[a], tb = closed[(b + 1) % n] - closed[b];
      const Vec3& t_over = a_over ? ta : tb;
      const Vec3& t_under = a_over ? tb : ta;
      const int sign = t_over.cross(t_under).dot(d) > 0 ? 1 : -1;
      passages.push_back({a + s, GaussEntry{crossing, a_over, sign}});
      passages.push_back({b + t, GaussEntry{crossing, !a_over, sign}});
      ++crossing;
    }
  }
  std::sort(passages.begin(), passages.end(), [](const Passage& x, const Passage& y) {
    return x.at < y.at || (x.at == y.at && x.entry.crossing < y.entry.crossing);
  });
  std::vector<GaussEntry> code;
  code.reserve(passages.size());
  for (const Passage& p : passages) code.push_back(p.entry);
  return code;
}

void ReduceGaussCode(std::vector<GaussEntry>* code) {
  std::vector<GaussEntry>& c = *code;
  const auto erase_crossings = [&](int x, int y) {
    c.erase(std::remove_if(c.begin(), c.end(),
                           [&](const GaussEntry& e) { return e.crossing == x || e.crossing == y; }),
            c.end());
  };
  const auto other_passage = [&](int k) {
    for (int j = 0; j < static_cast<int>(c.size()); ++j)
      if (j != k && c[j].crossing == c[k].crossing) return j;
    return -1;
  };
  bool changed = true;
  while (changed && !c.empty()) {
    changed = false;
    const int m = static_cast<int>(c.size());
    for (int k = 0; k < m && !changed; ++k) {
      const GaussEntry& a = c[k];
      const GaussEntry& b = c[(k + 1) % m];
      if (a.crossing == b.crossing) {  // move I: a kink
        erase_crossings(a.crossing, a.crossing);
        changed = true;
      } else if (Nugatory(c, k)) {  // a kink with more curve in its loop
        erase_crossings(a.crossing, a.crossing);
        changed = true;
      } else if (a.over == b.over && a.sign == -b.sign) {  // move II candidate
        const int ja = other_passage(k), jb = other_passage((k + 1) % m);
        const int gap = std::abs(ja - jb);
        if (ja >= 0 && jb >= 0 && (gap == 1 || gap == m - 1)) {
          erase_crossings(a.crossing, b.crossing);
          changed = true;
        }
      }
    }
  }
}

std::int64_t KnotDeterminant(const std::vector<GaussEntry>& code) {
  const int m = static_cast<int>(code.size());
  const int n = m / 2;  // crossings = arcs (each crossing has one under passage)
  if (n <= 1) return 1;
  if (n > kMaxDeterminantCrossings) return -1;
  // Each passage's crossing, renumbered 0..n-1 in order of first appearance (the matrix row).
  std::vector<int> ids, row_of(static_cast<std::size_t>(m));
  for (int i = 0; i < m; ++i) {
    const int crossing = code[static_cast<std::size_t>(i)].crossing;
    const auto it = std::find(ids.begin(), ids.end(), crossing);
    row_of[static_cast<std::size_t>(i)] = static_cast<int>(it - ids.begin());
    if (it == ids.end()) ids.push_back(crossing);
  }
  if (static_cast<int>(ids.size()) != n) return -1;  // not two passages per crossing
  // Arc k starts after the k-th under passage (in code order) and ends at the next one: an under
  // passage ends arc (k - 1) and starts arc k; an over passage lies on the arc it interrupts.
  std::vector<int> unders_before(static_cast<std::size_t>(m), 0);
  int unders = 0;
  for (int i = 0; i < m; ++i) {
    unders_before[static_cast<std::size_t>(i)] = unders;
    if (!code[static_cast<std::size_t>(i)].over) ++unders;
  }
  if (unders != n) return -1;
  const auto arc_before = [&](int i) {
    return (unders_before[static_cast<std::size_t>(i)] + n - 1) % n;
  };
  // Colouring matrix: per crossing, 2 x (over arc) - (arc in) - (arc out) (Fox; Alexander at -1).
  std::vector<__int128> a(static_cast<std::size_t>(n) * static_cast<std::size_t>(n), 0);
  const auto at = [&](int r, int c) -> __int128& {
    return a[static_cast<std::size_t>(r) * static_cast<std::size_t>(n) +
             static_cast<std::size_t>(c)];
  };
  for (int i = 0; i < m; ++i) {
    const int row = row_of[static_cast<std::size_t>(i)];
    if (code[static_cast<std::size_t>(i)].over) {
      at(row, arc_before(i)) += 2;
    } else {
      at(row, arc_before(i)) -= 1;                                   // the arc that ends here
      at(row, unders_before[static_cast<std::size_t>(i)] % n) -= 1;  // the arc that starts here
    }
  }
  // |det| of the minor without row 0 and column 0: fraction-free (Bareiss) elimination, exact.
  const int k = n - 1;
  const auto minor = [&](int r, int c) -> __int128& { return at(r + 1, c + 1); };
  __int128 prev = 1;
  int sign = 1;
  for (int p = 0; p < k; ++p) {
    int pivot = p;
    while (pivot < k && minor(pivot, p) == 0) ++pivot;
    if (pivot == k) return 0;
    if (pivot != p) {
      for (int c = 0; c < k; ++c) std::swap(minor(p, c), minor(pivot, c));
      sign = -sign;
    }
    for (int r = p + 1; r < k; ++r) {
      for (int c = p + 1; c < k; ++c)
        minor(r, c) = (minor(r, c) * minor(p, p) - minor(r, p) * minor(p, c)) / prev;
      minor(r, p) = 0;
    }
    prev = minor(p, p);
  }
  const __int128 det = sign * minor(k - 1, k - 1);
  return static_cast<std::int64_t>(det < 0 ? -det : det);
}

KnotIdentification IdentifyKnot(const std::vector<Vec3>& strand) {
  const std::vector<Vec3> closed = CloseStrand(strand);
  const std::array<Vec3, 13> directions = ProjectionDirections(strand);
  std::array<KnotIdentification, 13> votes;
  for (std::size_t k = 0; k < directions.size(); ++k) {
    std::vector<GaussEntry> code = GaussCode(closed, directions[k]);
    ReduceGaussCode(&code);
    votes[k] = Classify(code);
    ClassifyByDeterminant(code, &votes[k]);
  }
  // Majority; ties go to the class seen first in direction order (axes before diagonals).
  KnotIdentification best;
  for (std::size_t k = 0; k < votes.size(); ++k) {
    int count = 0;
    for (const KnotIdentification& v : votes) count += SameClass(v, votes[k]) ? 1 : 0;
    if (count > best.votes) {
      best = votes[k];
      best.votes = count;
    }
  }
  best.projections = static_cast<int>(directions.size());
  return best;
}

KnotIdentification IdentifyKnot(const std::vector<Vec3>& limb_a, const std::vector<Vec3>& limb_b) {
  std::vector<Vec3> strand(limb_a.rbegin(), limb_a.rend());
  strand.insert(strand.end(), limb_b.begin(), limb_b.end());
  return IdentifyKnot(strand);
}

}  // namespace arthrosim::instruments
