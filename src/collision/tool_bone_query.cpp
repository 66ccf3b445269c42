#include "arthrosim/collision/tool_bone_query.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "arthrosim/collision/proximity.h"

namespace arthrosim::collision {
namespace {

// Relative tolerance under which two triangle distances count as equally near (their face
// normals are summed into the pseudo-normal that tells inside from outside at edges/vertices).
constexpr double kTieRelative = 1e-9;
// Below this distance (mm) the closest-point direction is meaningless: use the pseudo-normal.
constexpr double kMinDirection = 1e-9;

Box CoreBox(const Simplex& s) {
  Box b;
  for (int i = 0; i < s.n; ++i) b.Add(s.v[i]);
  return b;
}

double BoxDistance(const Box& a, const Box& b) {
  double d2 = 0;
  for (int k = 0; k < 3; ++k) {
    const double g = std::max(std::max(a.lo[k] - b.hi[k], b.lo[k] - a.hi[k]), 0.0);
    d2 += g * g;
  }
  return std::sqrt(d2);
}

// A lower bound of the distance from any point of box b to the core: the box-box distance, and
// for a segment also a separating plane through the segment point p* nearest the box centre c,
// normal u = (c - p*) / |c - p*|: every segment point lies on its side (u . p <= u . p*, p*
// being nearest), the box within the half extent w = sum_k |u_k| h_k of c along u, so the
// distance is at least |c - p*| - w. For the thin boxes of surface triangles w is far below the
// box's half diagonal (a shaft over the humeral head gathered ~1 800 candidate triangles per
// query with the half diagonal in its place, ~110 with w). `loose` gives the half-diagonal bound
// (see ToolBoneClearance for why it is kept).
double CoreBoxLowerBound(const Simplex& core, const Box& core_box, const Box& b, bool loose) {
  double lower = BoxDistance(core_box, b);
  if (core.n == 2) {
    const Vec3 centre = 0.5 * (b.lo + b.hi);
    const Vec3 half = 0.5 * (b.hi - b.lo);
    const ClosestPair c = PointSegment(centre, core.v[0], core.v[1]);
    const double dist = std::sqrt(c.dist2);
    if (loose) {
      lower = std::max(lower, dist - half.norm());
    } else if (dist > 0) {
      const Vec3 u = (centre - c.pb) / dist;
      lower = std::max(lower, dist - u.cwiseAbs().dot(half));
    }
  }
  return lower;
}

Vec3 FaceNormal(const BoneQueryWorld::Entry& e, std::int32_t t) {
  const mesh::Tri& tri = e.tris[static_cast<std::size_t>(t)];
  const Vec3& a = e.positions[static_cast<std::size_t>(tri[0])];
  const Vec3 n = (e.positions[static_cast<std::size_t>(tri[1])] - a)
                     .cross(e.positions[static_cast<std::size_t>(tri[2])] - a);
  const double len = n.norm();
  return len > 0 ? Vec3(n / len) : Vec3::UnitZ();
}

// Nearest of the candidate triangles to the core, with the pseudo-normal of the ties; the
// signed distance of the core from the surface (> 0 outside) and the way out.
struct CoreNearest {
  bool found = false;
  double signed_mm = 0;
  Vec3 point = Vec3::Zero();
  Vec3 out = Vec3::UnitZ();
};

// Pruning (the answer is bit for bit that of testing every candidate): the exact distance to
// the candidate whose box is nearest bounds the nearest distance from above by `bound`; a
// candidate whose box lower bound exceeds bound (1 + kPruneRelative) + kPruneAbsoluteMm can be
// neither nearer nor a tie at any point of the scan (the running best never exceeds the nearest
// distance by more than the tie tolerance), so it is skipped without its exact test. The scan
// keeps the candidates' order, so the pseudo-normal sums run in the same order.
constexpr double kPruneRelative = 1e-6;
constexpr double kPruneAbsoluteMm = 1e-9;

ClosestPair ExactToTriangle(const Simplex& core, const BoneQueryWorld::Entry& e, std::int32_t t) {
  const mesh::Tri& tri = e.tris[static_cast<std::size_t>(t)];
  return Closest(core, TriangleSimplex(e.positions[static_cast<std::size_t>(tri[0])],
                                       e.positions[static_cast<std::size_t>(tri[1])],
                                       e.positions[static_cast<std::size_t>(tri[2])]));
}

// The nearest of the tested candidates (in the order given: ascending triangle index), with the
// pseudo-normal of the ties; `any` false: no candidate (not found).
CoreNearest Scan(const BoneQueryWorld::Entry& e, const std::vector<BoneQueryWorld::Tested>& tested,
                 bool any) {
  CoreNearest r;
  double best2 = std::numeric_limits<double>::infinity();
  ClosestPair best_pair;
  Vec3 pseudo = Vec3::Zero();
  for (const BoneQueryWorld::Tested& x : tested) {
    const ClosestPair& c = x.pair;
    if (c.dist2 < best2 * (1 - kTieRelative)) {
      best2 = c.dist2;
      best_pair = c;
      pseudo = FaceNormal(e, x.tri);
    } else if (c.dist2 <= best2 * (1 + kTieRelative)) {
      pseudo += FaceNormal(e, x.tri);
    }
  }
  if (!any) return r;
  r.found = true;
  const double dist = std::sqrt(best2);
  const Vec3 delta = best_pair.pa - best_pair.pb;
  const double pn = pseudo.norm();
  const Vec3 pseudo_unit = pn > 0 ? Vec3(pseudo / pn) : Vec3::UnitZ();
  const bool outside = delta.dot(pseudo_unit) >= 0;
  r.signed_mm = outside ? dist : -dist;
  r.point = best_pair.pb;
  if (dist > kMinDirection) {
    r.out = outside ? Vec3(delta / dist) : Vec3(-delta / dist);
  } else {
    r.out = pseudo_unit;
  }
  return r;
}

CoreNearest NearestTo(const Simplex& core, const BoneQueryWorld::Entry& e,
                      const std::vector<std::int32_t>& cand, bool loose, BoneQueryWorld* world) {
  auto exact = [&](std::int32_t t) { return ExactToTriangle(core, e, t); };
  std::vector<double>* lower = &world->lower_bounds;
  const Box core_box = CoreBox(core);
  lower->resize(cand.size());
  std::size_t nearest_box = 0;
  for (std::size_t i = 0; i < cand.size(); ++i) {
    (*lower)[i] = CoreBoxLowerBound(core, core_box, e.bvh.TriangleBox(cand[i]), loose);
    if ((*lower)[i] < (*lower)[nearest_box]) nearest_box = i;
  }
  const double bound = cand.empty() ? 0.0 : std::sqrt(exact(cand[nearest_box]).dist2);
  world->exact_tests += cand.empty() ? 0 : 1;
  const double cutoff = bound * (1 + kPruneRelative) + kPruneAbsoluteMm;
  world->tested.clear();
  for (std::size_t i = 0; i < cand.size(); ++i) {
    if ((*lower)[i] > cutoff) continue;
    world->tested.push_back({cand[i], exact(cand[i])});
    ++world->exact_tests;
  }
  return Scan(e, world->tested, !cand.empty());
}

// True if a plane proves triangle t of e farther than cutoff_mm from the core: every core vertex
// strictly on one side of the triangle's plane, the nearest of them farther than cutoff_mm from
// it (the core is their convex hull, the triangle lies in the plane). Much tighter than a box
// bound for the walls of a hole around a shaft (a wall triangle's box reaches toward the axis).
bool PlaneSeparated(const Simplex& core, const BoneQueryWorld::Entry& e, std::int32_t t,
                    double cutoff_mm) {
  const mesh::Tri& tri = e.tris[static_cast<std::size_t>(t)];
  const Vec3& a = e.positions[static_cast<std::size_t>(tri[0])];
  const Vec3 n = (e.positions[static_cast<std::size_t>(tri[1])] - a)
                     .cross(e.positions[static_cast<std::size_t>(tri[2])] - a);
  const double nn = n.squaredNorm();
  if (!(nn > 0)) return false;
  double nearest = std::numeric_limits<double>::infinity();
  int above = 0, below = 0;
  for (int i = 0; i < core.n; ++i) {
    const double side = n.dot(core.v[static_cast<std::size_t>(i)] - a);
    above += side > 0 ? 1 : 0;
    below += side < 0 ? 1 : 0;
    nearest = std::min(nearest, std::abs(side));
  }
  if (above != core.n && below != core.n) return false;
  return nearest * nearest > cutoff_mm * cutoff_mm * nn;
}

// The nearest triangle of bone e to a core when it lies well within `search` (its distance at
// most search (1 - kPruneRelative) - kPruneAbsoluteMm): true and *out; false (*out untouched)
// otherwise, where the gathering search below decides (its answer beyond the search distance
// depends on the candidates it gathers, which the proxy relies on).
//
// Best-first over the tree by the box lower bound: each triangle reached that no plane proves
// too far is tested exactly and lowers the cutoff to its distance (1 + kPruneRelative) +
// kPruneAbsoluteMm, so the search ends at the nearest distance d plus that margin instead of
// gathering all that lies within a first guess (the greedy descent's triangle: in the awl's own
// hole ~2 900 candidates for ~100 that can matter). The scan (Scan, in triangle order) then sees
// exactly the triangles within the final cutoff, C = d (1 + 1e-6) + 1e-9 mm: the same answer, bit
// for bit, as the gathering search (NearestOfBone) and as testing every triangle, which see
// these and possibly more, all farther than C. A farther triangle cannot change the scan: once
// the nearest is scanned the running best stays within the tie tolerance (1e-9 relative) of it,
// so no farther one ties or replaces; before, a farther one is replaced by the nearest (or a
// nearer one) and leaves no trace, unless a chain of triangles, each a tie (within 1e-9) of the
// next, leads from it down to the nearest, which needs ~1 000 triangles between d and C.
bool NearestWithin(const Simplex& core, const Box& core_box, const BoneQueryWorld::Entry& e,
                   double search, BoneQueryWorld* world, CoreNearest* out) {
  auto lower = [&](const Box& b) { return CoreBoxLowerBound(core, core_box, b, false); };
  std::vector<BoneQueryWorld::Tested>& tested = world->tested;
  tested.clear();
  double cutoff = search;
  double nearest = std::numeric_limits<double>::infinity();
  e.bvh.BestFirst(
      lower, &cutoff,
      [&](std::int32_t t, double) {
        ++world->gathered;
        if (PlaneSeparated(core, e, t, cutoff)) return;
        const ClosestPair c = ExactToTriangle(core, e, t);
        ++world->exact_tests;
        const double d = std::sqrt(c.dist2);
        if (!(d <= cutoff)) return;
        tested.push_back({t, c});
        if (d < nearest) {
          nearest = d;
          cutoff = std::min(search, nearest * (1 + kPruneRelative) + kPruneAbsoluteMm);
        }
      },
      &world->heap);
  // Those within the final cutoff, in triangle order (the scan's order).
  tested.erase(std::remove_if(tested.begin(), tested.end(),
                              [&](const BoneQueryWorld::Tested& x) {
                                return !(std::sqrt(x.pair.dist2) <= cutoff);
                              }),
               tested.end());
  if (tested.empty()) return false;
  std::sort(tested.begin(), tested.end(),
            [](const BoneQueryWorld::Tested& a, const BoneQueryWorld::Tested& b) {
              return a.tri < b.tri;
            });
  const CoreNearest n = Scan(e, tested, true);
  if (!(std::abs(n.signed_mm) <= search * (1 - kPruneRelative) - kPruneAbsoluteMm)) return false;
  *out = n;
  return true;
}

// The nearest triangle of bone e to a core, searched within `search` of it (see
// ToolBoneClearance). Only triangles that can be the nearest or tie with it are gathered: an upper
// bound u of the nearest distance (the exact distance to the triangle Descend reaches) caps the
// search at u (1 + kPruneRelative) + kPruneAbsoluteMm (see NearestTo; the triangle itself is
// gathered, so the nearest distance is <= u).
CoreNearest NearestOfBone(const Simplex& core, const Box& core_box, const BoneQueryWorld::Entry& e,
                          double search, bool loose, BoneQueryWorld* world) {
  auto lower = [&](const Box& b) { return CoreBoxLowerBound(core, core_box, b, loose); };
  double cutoff = search;
  const std::int32_t first = e.bvh.Descend(lower);
  if (first >= 0) {
    const double u = std::sqrt(ExactToTriangle(core, e, first).dist2);
    ++world->exact_tests;
    cutoff = std::min(search, u * (1 + kPruneRelative) + kPruneAbsoluteMm);
  }
  std::vector<std::int32_t>& cand = world->candidates;
  cand.clear();
  e.bvh.QueryIf([&](const Box& b) { return lower(b) <= cutoff; }, &cand);
  world->gathered += static_cast<std::int64_t>(cand.size());
  return NearestTo(core, e, cand, loose, world);
}

}  // namespace

void SyncBoneQuery(const State& state, BoneQueryWorld* world) {
  if (world->bones.size() != state.bones.size()) ++world->generation;
  world->bones.resize(state.bones.size());
  for (std::size_t g = 0; g < state.bones.size(); ++g) {
    const mesh::TriMesh& m = state.bones[g].surface;
    BoneQueryWorld::Entry& e = world->bones[g];
    const bool same = e.built && e.revision == state.bones[g].revision &&
                      e.positions.size() == static_cast<std::size_t>(m.nodes.cols()) &&
                      e.tris.size() == m.tris.size();
    if (same) continue;
    e.positions.resize(static_cast<std::size_t>(m.nodes.cols()));
    for (Eigen::Index i = 0; i < m.nodes.cols(); ++i) {
      e.positions[static_cast<std::size_t>(i)] = m.nodes.col(i);
    }
    e.tris = m.tris;
    e.bvh.Build(e.positions, e.tris);
    e.revision = state.bones[g].revision;
    e.built = true;
    ++world->generation;
  }
}

ToolBoneHit ToolBoneClearance(const std::vector<ToolPrimitive>& primitives, double reach_mm,
                              BoneQueryWorld* world) {
  ToolBoneHit hit;
  hit.clearance_mm = reach_mm;
  for (std::size_t p = 0; p < primitives.size(); ++p) {
    const ToolPrimitive& prim = primitives[p];
    if (!prim.contacts) continue;
    const Box core_box = CoreBox(prim.core);
    const double search = prim.radius_mm + reach_mm;
    for (std::size_t g = 0; g < world->bones.size(); ++g) {
      const BoneQueryWorld::Entry& e = world->bones[g];
      if (e.bvh.empty() || BoxDistance(core_box, e.bvh.Bounds()) > search) continue;
      // Well within reach the best-first search answers (NearestWithin). Otherwise the gathering
      // search does; within reach the tight bound gathers fewer candidates for the same answer.
      // Beyond it (no triangle within `search`) the answer is whatever the gathered candidates
      // give: the half-diagonal bound gathers some that lie farther and so sees some cores deeper
      // inside than the reach, which the proxy relies on; that case keeps the loose bound's answer,
      // bit for bit, until a depth-proof inside test replaces it.
      CoreNearest n;
      if (!NearestWithin(prim.core, core_box, e, search, world, &n)) {
        n = NearestOfBone(prim.core, core_box, e, search, false, world);
        const bool beyond =
            !n.found || std::abs(n.signed_mm) > search * (1 - kPruneRelative) - kPruneAbsoluteMm;
        if (beyond && prim.core.n == 2)
          n = NearestOfBone(prim.core, core_box, e, search, true, world);
      }
      if (!n.found) continue;
      const double clearance = n.signed_mm - prim.radius_mm;
      if (clearance < hit.clearance_mm) {
        hit.clearance_mm = clearance;
        hit.bone = static_cast<std::int32_t>(g);
        hit.primitive = static_cast<std::int32_t>(p);
        hit.point_mm = n.point;
        hit.normal = n.out;
      }
    }
  }
  return hit;
}

double PointBoneSignedDistance(const Vec3& p, BoneQueryWorld* world) {
  double best = std::numeric_limits<double>::infinity();
  std::vector<std::int32_t>& cand = world->candidates;
  const Simplex point = PointSimplex(p);
  for (const BoneQueryWorld::Entry& e : world->bones) {
    if (e.bvh.empty()) continue;
    Box query;
    query.Add(p);
    // Grow the search box until it holds a triangle; the nearest one is then within the
    // distance to that triangle's farthest box corner, so one more query of that radius is exact.
    double radius = 1.0;
    cand.clear();
    for (int k = 0; k < 64 && cand.empty(); ++k) {
      e.bvh.Query(query.Inflated(radius), &cand);
      radius *= 2;
    }
    if (cand.empty()) continue;  // not a finite point
    double reach = 0;
    for (const std::int32_t t : cand) {
      const Box& b = e.bvh.TriangleBox(t);
      for (int k = 0; k < 8; ++k) {
        const Vec3 corner((k & 1) ? b.hi.x() : b.lo.x(), (k & 2) ? b.hi.y() : b.lo.y(),
                          (k & 4) ? b.hi.z() : b.lo.z());
        reach = std::max(reach, (corner - p).norm());
      }
    }
    cand.clear();
    e.bvh.Query(query.Inflated(reach), &cand);
    const CoreNearest n = NearestTo(point, e, cand, false, world);
    if (n.found) best = std::min(best, n.signed_mm);  // inside any bone wins
  }
  return best;
}

}  // namespace arthrosim::collision
