// Collision stage, soft body tasks: a soft body's surface against bones (its vertices against
// the bone surface, the bone's salient corners against its triangles) and against the other
// soft bodies (its vertices against their triangles, a contact on both sides).
#include <algorithm>
#include <cmath>

#include "contact_internal.h"

namespace arthrosim::collision::internal {

// ---- soft tissue against bone -----------------------------------------------------------------

// Bone triangles whose box overlaps `query`, ascending, through entry i of *cache: its list was
// made for a wider box and is refreshed when `query` leaves it or the bone changed.
constexpr double kNearBoneSlack = 0.5;  // mm; soft tissue and threads move far less per step

void NearBoneTriangles(const CollisionWorld::BoneEntry& g, NearBoneCache* cache, std::size_t i,
                       const Box& query, std::vector<std::int32_t>* out) {
  out->clear();
  const Box& w = cache->wide[i];
  if (!cache->valid[i] || (query.lo.array() < w.lo.array()).any() ||
      (query.hi.array() > w.hi.array()).any()) {
    std::vector<std::int32_t>& list = cache->tris[i];
    list.clear();
    cache->wide[i] = query.Inflated(kNearBoneSlack);
    g.bvh.Query(cache->wide[i], &list);
    cache->valid[i] = 1;
  }
  for (std::int32_t t : cache->tris[i]) {
    if (g.bvh.TriangleBox(t).Overlaps(query)) out->push_back(t);
  }
}

void ResetNearBone(std::int64_t version, std::size_t slots, NearBoneCache* cache) {
  if (cache->bone_version == version && cache->wide.size() == slots) return;
  cache->bone_version = version;
  cache->wide.assign(slots, Box{});
  cache->valid.assign(slots, 0);
  cache->tris.assign(slots, {});
  cache->far_at.assign(slots, Vec3::Zero());
  cache->far_margin.assign(slots, -1.0);
  cache->hint.assign(slots, -1);
}

namespace {

// After NearBoneTriangles(g, cache, i, query, ...): a lower bound of the distance from `from` (a
// point inside `query`) to every bone triangle it left out (mm): the nearest left-out box in the
// list, or the wide box's faces, beyond which no unlisted triangle lies.
double LeftOutLowerBound(const CollisionWorld::BoneEntry& g, const NearBoneCache& cache,
                         std::size_t i, const Box& query, const Vec3& from) {
  const Box& w = cache.wide[i];
  const Box at{from, from};
  double lower2 = std::pow(std::min((w.hi - from).minCoeff(), (from - w.lo).minCoeff()), 2);
  for (std::int32_t t : cache.tris[i]) {
    const Box& b = g.bvh.TriangleBox(t);
    if (!b.Overlaps(query)) lower2 = std::min(lower2, BoxDist2(at, b));
  }
  return std::sqrt(lower2);
}

void TissueBone(ContactBuilder* cb, int body, CollisionWorld::SoftEntry& s, int bone,
                CollisionWorld::BoneEntry& g) {
  const CollisionParams& P = cb->params;
  if (s.bvh.empty() || g.bvh.empty()) return;
  const double margin = std::max(P.alarm_distance_mm, P.max_depth_mm);
  if (!s.bvh.Bounds().Inflated(margin + kNearBoneSlack).Overlaps(g.bvh.Bounds())) return;
  NearBoneCache& cache = s.near_bone[bone];
  ResetNearBone(g.version, s.positions.size(), &cache);
  std::vector<std::int32_t>& cand = cb->scratch.cand;
  for (std::size_t vi = 0; vi < s.positions.size(); ++vi) {
    const std::int32_t v = static_cast<std::int32_t>(vi);
    const std::int32_t node = s.surface.vertices[v];
    if (s.fixed[vi]) continue;
    const Vec3& p = s.positions[v];
    // Still within the bound of an earlier search that found it clearly out of contact: the
    // same search now would too (no contact; the candidate cache is only a shortcut).
    if (cache.far_margin[vi] > 0 && (p - cache.far_at[vi]).norm() < cache.far_margin[vi]) continue;
    cache.far_margin[vi] = -1;
    const Box query{p.array() - margin, p.array() + margin};
    NearBoneTriangles(g, &cache, vi, query, &cand);
    const Nearest n = cand.empty()
                          ? Nearest{}
                          : NearestOnSurface(PointSimplex(p), Box{p, p}, cand, g.bvh, g.positions,
                                             g.indexed.local_tris, &cb->scratch, cache.hint[vi]);
    if (n.found) cache.hint[vi] = n.tri;
    const double sd = n.found ? n.Signed() : margin;
    if (!n.found || (sd >= 0 ? sd >= P.alarm_distance_mm : -sd >= P.max_depth_mm)) {
      // No contact. The unsigned distance to the bone is at least `lower`; while the vertex
      // moves less than lower - margin it stays beyond both contact ranges (alarm outside,
      // max depth inside), so every search would find no contact.
      const double rest = LeftOutLowerBound(g, cache, vi, query, p);  // triangles not searched
      const double lower = n.found ? std::min(n.dist, rest) : rest;
      double bound = lower - margin - kCertSlack;
      // Outside a closed surface within `margin` (so the search saw every triangle that near
      // and the sign is exact), the signed distance is 1-Lipschitz: after moving less than
      // sd - alarm the vertex is still out of reach. (Around the rim of an open surface the
      // sign may flip; beyond `margin` the search only bounds the distance from above.)
      if (n.found && g.closed && sd < margin) {
        bound = std::max(bound, sd - P.alarm_distance_mm - kCertSlack);
      }
      if (bound > 0) {
        cache.far_at[vi] = p;
        cache.far_margin[vi] = bound;
      }
      continue;
    }
    PointContact c;
    c.target = PointContact::Target::kSoftBody;
    c.index = body;
    c.nodes = {node, -1, -1, -1};
    c.weights = {1, 0, 0, 0};
    c.normal = sd > kMinDirection ? Vec3((n.pair.pa - n.pair.pb) / n.dist) : n.pseudo;
    c.offset_mm = c.normal.dot(n.pair.pb) + P.contact_distance_mm;
    c.stiffness_n_per_mm = P.bone_stiffness_n_per_mm;
    c.obstacle_id = bone;
    cb->Add(c, Kind::kBone);
  }
}

// ---- soft points searched out to a distance --------------------------------------------------

// The nearest point of soft surface `s` to p, searched out to `wide` (leaving out the triangles
// `skip` marks, if given); *lower: a lower bound of the distance from p to the surface (the
// searched box, or the nearest triangle).
Nearest NearestSoftPoint(ContactBuilder* cb, const CollisionWorld::SoftEntry& s, const Box& bounds,
                         const Vec3& p, double wide, const std::vector<std::uint8_t>* skip,
                         double* lower) {
  *lower = wide;
  Nearest n;
  if (NearBoxes(Box{p, p}, wide, bounds)) {
    std::vector<std::int32_t>& cand = cb->scratch.cand;
    cand.clear();
    s.bvh.Query(Box{p.array() - wide, p.array() + wide}, &cand);
    if (skip != nullptr) {
      cand.erase(
          std::remove_if(cand.begin(), cand.end(), [&](std::int32_t t) { return (*skip)[t] != 0; }),
          cand.end());
    }
    n = NearestOnSurface(PointSimplex(p), Box{p, p}, cand, s.bvh, s.positions, s.surface.local_tris,
                         &cb->scratch);
    if (n.found) *lower = std::min(*lower, n.dist);
  } else {
    *lower = std::max(wide, std::sqrt(BoxDist2(Box{p, p}, bounds)));
  }
  return n;
}

// When lower >= reach (|signed distance| >= reach: no contact either side of the surface),
// keeps point i at p as out of reach by the margin left, and returns true.
bool KeepFarBound(FarBounds* far, std::size_t i, const Vec3& p, double lower, double reach,
                  double drift_mm) {
  if (lower < reach) return false;
  far->at[i] = p;
  far->margin[i] = lower - reach - kCertSlack;
  far->drift0[i] = drift_mm;
  return true;
}

// ---- soft tissue against soft tissue (different bodies) ------------------------------------

// Surface vertices of body a near the surface of body b: contact on both sides, as for a thread
// on tissue (vertex of a along +n, the nearest point of b's triangle along -n; n out of b).
// Called for both orders of a pair, so each side's vertices meet the other's triangles. Joined
// bodies: vertices near the join at rest and triangles touching a joined node are left out (the
// interface is inside the merged body).
void TissueTissue(ContactBuilder* cb, int a, CollisionWorld::SoftEntry& ea, int b,
                  const CollisionWorld::SoftEntry& eb) {
  const CollisionParams& P = cb->params;
  if (ea.bvh.empty() || eb.bvh.empty()) return;
  const double reach = std::max(P.alarm_distance_mm, P.max_depth_mm);
  const Box bounds = eb.bvh.Bounds();
  if (!ea.bvh.Bounds().Inflated(reach).Overlaps(bounds)) return;
  const std::vector<std::uint8_t>* skip_v =
      static_cast<std::size_t>(b) < ea.join_vertex.size() && !ea.join_vertex[b].empty()
          ? &ea.join_vertex[b]
          : nullptr;
  const std::vector<std::uint8_t>* skip_t =
      static_cast<std::size_t>(a) < eb.join_tri.size() && !eb.join_tri[a].empty() ? &eb.join_tri[a]
                                                                                  : nullptr;
  FarBounds& far = ea.far_soft[b];
  far.Reset(ea.version, eb.version, ea.positions.size());
  // Searched out to `wide`: a vertex found farther than reach keeps the difference as a bound.
  const double wide = reach + kFarSlack;
  for (std::size_t vi = 0; vi < ea.positions.size(); ++vi) {
    if (skip_v != nullptr && (*skip_v)[vi]) continue;
    const Vec3& p = ea.positions[vi];
    if (far.Holds(vi, p, eb.drift_mm)) continue;
    far.margin[vi] = -1;
    double lower = 0;
    const Nearest n = NearestSoftPoint(cb, eb, bounds, p, wide, skip_t, &lower);
    if (KeepFarBound(&far, vi, p, lower, reach, eb.drift_mm)) continue;
    const double sd = n.Signed();
    if (sd >= 0 ? sd >= P.alarm_distance_mm : -sd >= P.max_depth_mm) continue;
    const Vec3 normal = sd > kMinDirection ? Vec3((n.pair.pa - n.pair.pb) / n.dist) : n.pseudo;
    // Both sides move: each plane is half-way, so that two stiff responses meet at the skin
    // distance instead of each jumping to the other's old place (which overshoots by the
    // penetration and rings). A side that cannot move (all fixed) leaves the whole gap to the
    // other.
    const mesh::Tri& g = eb.surface.tris[n.tri];
    const bool a_moves = !ea.fixed[vi];
    const bool b_moves =
        !(cb->SoftFixed(b, g[0]) && cb->SoftFixed(b, g[1]) && cb->SoftFixed(b, g[2]));
    const double ha = normal.dot(n.pair.pa), hb = normal.dot(n.pair.pb);
    const double mid = 0.5 * (ha + hb), skin = P.contact_distance_mm;
    if (a_moves) {
      PointContact c;
      c.target = PointContact::Target::kSoftBody;
      c.index = a;
      c.nodes = {ea.surface.vertices[vi], -1, -1, -1};
      c.weights = {1, 0, 0, 0};
      c.normal = normal;
      c.offset_mm = b_moves ? mid + 0.5 * skin : hb + skin;
      c.stiffness_n_per_mm = P.tissue_tissue_stiffness_n_per_mm;
      c.obstacle_id = b;
      cb->Add(c, Kind::kSoftBody);
    }
    if (b_moves) {
      cb->Add(SoftTrianglePoint(b, g, n.pair.wb, -normal, a_moves ? -mid + 0.5 * skin : -ha + skin,
                                P.tissue_tissue_stiffness_n_per_mm, a),
              Kind::kSoftBody);
    }
  }
}

// ---- salient bone vertices against soft triangles ---------------------------------------------

// A bone corner (spur tip) near or inside a soft surface whose nearest soft point is inside a
// triangle or on an edge (at a soft vertex, tissue-bone already holds it): that soft point is
// pushed away from the corner, to contact_distance beyond it along the soft surface normal.
void BoneTipTissue(ContactBuilder* cb, int body, const CollisionWorld::SoftEntry& s, int bone,
                   CollisionWorld::BoneEntry& g) {
  const CollisionParams& P = cb->params;
  if (s.bvh.empty() || g.salient.empty()) return;
  const double reach = std::max(P.alarm_distance_mm, P.max_depth_mm);
  const double wide = reach + kFarSlack;
  const Box bounds = s.bvh.Bounds();
  FarBounds& far = g.far_soft[body];
  far.Reset(g.version, s.version, g.salient.size());
  for (std::size_t i = 0; i < g.salient.size(); ++i) {
    const Vec3& p = g.positions[g.salient[i]];
    if (far.Holds(i, p, s.drift_mm)) continue;
    far.margin[i] = -1;
    double lower = 0;
    const Nearest n = NearestSoftPoint(cb, s, bounds, p, wide, nullptr, &lower);
    if (KeepFarBound(&far, i, p, lower, reach, s.drift_mm)) continue;
    const double sd = n.Signed();  // of the bone corner from the soft surface
    if (sd >= 0 ? sd >= P.alarm_distance_mm : -sd >= P.max_depth_mm) continue;
    const auto& w = n.pair.wb;
    if ((w[0] <= 0) + (w[1] <= 0) + (w[2] <= 0) >= 2) continue;  // at a soft vertex
    const mesh::Tri& t = s.surface.tris[n.tri];
    if (cb->SoftFixed(body, t[0]) && cb->SoftFixed(body, t[1]) && cb->SoftFixed(body, t[2]))
      continue;
    // n: out of the tissue toward the corner; the tissue point must stay behind the corner.
    const Vec3 normal = sd > kMinDirection ? Vec3((n.pair.pa - n.pair.pb) / n.dist) : n.pseudo;
    cb->Add(SoftTrianglePoint(body, t, w, -normal, -normal.dot(p) + P.contact_distance_mm,
                              P.bone_stiffness_n_per_mm, bone),
            Kind::kBone);
  }
}

}  // namespace

void DetectTissueBones(ContactBuilder* cb, int body, CollisionWorld* world) {
  const std::size_t b = static_cast<std::size_t>(body);
  for (std::size_t g = 0; g < world->bones.size(); ++g) {
    TissueBone(cb, body, world->soft[b], static_cast<int>(g), world->bones[g]);
    if (cb->params.bone_tip_contacts) {
      BoneTipTissue(cb, body, world->soft[b], static_cast<int>(g), world->bones[g]);
    }
  }
}

void DetectTissueTissue(ContactBuilder* cb, int body, CollisionWorld* world) {
  const std::size_t a = static_cast<std::size_t>(body);
  for (std::size_t b = 0; b < world->soft.size(); ++b) {
    if (b != a) TissueTissue(cb, body, world->soft[a], static_cast<int>(b), world->soft[b]);
  }
}

}  // namespace arthrosim::collision::internal
