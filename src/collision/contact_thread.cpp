// Collision stage, thread task: a thread's nodes and segments against every soft surface (a
// contact on both sides) and bone (thread side only).
#include <algorithm>
#include <cmath>

#include "contact_internal.h"

namespace arthrosim::collision::internal {
namespace {

// ---- thread against a surface (tissue: both sides; bone: thread side) ---------------------

// A thread point (node or segment interior) near a surface: thread-side contact, and for soft
// tissue the reaction contact on the surface point.
void ThreadSurfaceContact(ContactBuilder* cb, int thread, PointContact c, const Nearest& n,
                          Kind obstacle, int obstacle_index, const Surface& s, double rt,
                          double stiffness) {
  const CollisionParams& P = cb->params;
  const Vec3 normal =
      n.Signed() > kMinDirection ? Vec3((n.pair.pa - n.pair.pb) / n.dist) : n.pseudo;
  c.normal = normal;
  c.offset_mm = normal.dot(n.pair.pb) + rt + P.contact_distance_mm;
  c.stiffness_n_per_mm = stiffness;
  c.obstacle_id = obstacle_index;
  cb->Add(c, obstacle);
  if (obstacle != Kind::kSoftBody) return;
  const mesh::Tri& g = s.tris[n.tri];
  if (cb->SoftFixed(obstacle_index, g[0]) && cb->SoftFixed(obstacle_index, g[1]) &&
      cb->SoftFixed(obstacle_index, g[2])) {
    return;
  }
  cb->Add(SoftTrianglePoint(obstacle_index, g, n.pair.wb, -normal,
                            -normal.dot(n.pair.pa) + rt + P.contact_distance_mm, stiffness, thread),
          Kind::kThread);
}

// Whether the nearest surface point n is within contact range of a thread of radius rt: up to
// the alarm distance outside; inside, up to the maximum depth for tissue (deeper counts as a
// stitch passing through) and at any depth for bone (a suture never passes through bone).
bool InContact(const Nearest& n, double rt, const CollisionParams& P, Kind obstacle) {
  const double sd = n.Signed();
  if (sd >= 0) return sd < rt + P.alarm_distance_mm;
  return obstacle == Kind::kBone || -sd < P.max_depth_mm;
}

// Next to a piercing (scratch->pierced) the thread enters the tissue on purpose: blocks the
// segments beside it and their nodes (scratch->blocked_edge, blocked_node) from contacts.
void BlockAroundPiercings(const ThreadModel& tm, ContactTaskScratch* scratch) {
  const std::size_t ne = tm.initial.edges.size();
  for (std::size_t i = 0; i < ne; ++i) {
    if (!scratch->pierced[i]) continue;
    for (std::size_t j = i > 0 ? i - 1 : 0; j <= i + 1 && j < ne; ++j) scratch->blocked_edge[j] = 1;
  }
  for (std::size_t i = 0; i < ne; ++i) {
    if (scratch->blocked_edge[i]) {
      scratch->blocked_node[tm.initial.edges[i][0]] =
          scratch->blocked_node[tm.initial.edges[i][1]] = 1;
    }
  }
}

// Distance from p to triangle `tri` of the surface points `pos`.
double TriangleDistance(const Vec3& p, const std::vector<Vec3>& pos, const mesh::Tri& tri) {
  return std::sqrt(
      Closest(PointSimplex(p), TriangleSimplex(pos[tri[0]], pos[tri[1]], pos[tri[2]])).dist2);
}

// Segment interiors (a thread over an edge of the surface): a contact at the nearest point of a
// segment (scratch seg_nearest) that is not blocked, where the segment dips below its end nodes'
// distances (a real interior minimum).
void SegmentInteriorContacts(ContactBuilder* cb, int thread, Kind obstacle, int obstacle_index,
                             const Surface& s, const std::vector<Vec3>& pos, double rt,
                             double stiffness) {
  const ThreadModel& tm = cb->model.threads[thread];
  const Points& x = cb->state.threads[thread].x;
  const std::vector<Nearest>& seg = cb->scratch.seg_nearest;
  for (std::size_t i = 0; i < tm.initial.edges.size(); ++i) {
    const Nearest& n = seg[i];
    const double u = n.pair.wa[1];
    if (!n.found || cb->scratch.blocked_edge[i] || u <= 1e-9 || u >= 1 - 1e-9 ||
        !InContact(n, rt, cb->params, obstacle)) {
      continue;
    }
    const std::int32_t a = tm.initial.edges[i][0], b = tm.initial.edges[i][1];
    if (cb->ThreadFixed(thread, a) && cb->ThreadFixed(thread, b)) continue;
    const mesh::Tri& tri = s.local_tris[n.tri];
    const double da = TriangleDistance(x.col(a), pos, tri);
    const double db = TriangleDistance(x.col(b), pos, tri);
    if (n.dist >= std::min(da, db) - 1e-9) continue;
    ThreadSurfaceContact(cb, thread, ThreadPoint(thread, a, b, u), n, obstacle, obstacle_index, s,
                         rt, stiffness);
  }
}

// `query(i, box, out)` lists the triangles whose box overlaps `box` (ascending) for query slot i
// (segment i - n for i >= n, n = node count; slots below n are left for node queries): a tree
// query, or a NearBoneCache lookup for a bone.
// `batch`: segment candidates come from `bvh` by one query per run of segments instead.
// `hint`: per node then segment, the last nearest triangle (search hints, kept by the caller).
template <class Query>
void ThreadSurface(ContactBuilder* cb, int thread, Kind obstacle, int obstacle_index,
                   const Surface& s, const std::vector<Vec3>& pos, const TriangleBvh& bvh,
                   double stiffness, bool batch, std::vector<std::int32_t>* hint,
                   const Query& query) {
  const CollisionParams& P = cb->params;
  const ThreadModel& tm = cb->model.threads[thread];
  const Points& x = cb->state.threads[thread].x;
  const double rt = 0.5 * tm.diameter_mm;
  if (bvh.empty()) return;
  const Box bounds = bvh.Bounds();
  const double reach = std::max(rt + P.alarm_distance_mm, P.max_depth_mm);
  // Bone: a node that went deeper than `reach` still finds the surface that pushes it out, down
  // to thread_bone_reach_mm below the alarm band (its own query, below); 0 for tissue.
  const double deep_reach =
      obstacle == Kind::kBone ? rt + P.alarm_distance_mm + P.thread_bone_reach_mm : 0.0;
  const std::size_t ne = tm.initial.edges.size();
  const Eigen::Index nn = x.cols();
  ContactTaskScratch& scratch = cb->scratch;
  std::vector<std::int32_t>& tris = scratch.tris;
  std::vector<Nearest>& seg = scratch.seg_nearest;
  std::vector<std::vector<std::int32_t>>& seg_tris = scratch.seg_tris;  // candidates per segment
  std::vector<std::int32_t>& node_seg =
      scratch.node_seg;  // a segment with candidates near the node
  std::vector<std::uint8_t>& pierced = scratch.pierced;
  std::vector<std::uint8_t>& blocked_edge = scratch.blocked_edge;
  std::vector<std::uint8_t>& blocked_node = scratch.blocked_node;
  std::vector<std::uint8_t>& near_node = scratch.near_node;
  seg.assign(ne, Nearest{});
  if (hint->size() != static_cast<std::size_t>(nn) + ne) hint->assign(nn + ne, -1);
  if (seg_tris.size() < ne) seg_tris.resize(ne);
  node_seg.assign(static_cast<std::size_t>(nn), -1);
  pierced.assign(ne, 0);
  blocked_edge.assign(ne, 0);
  blocked_node.assign(static_cast<std::size_t>(nn), 0);
  near_node.assign(static_cast<std::size_t>(nn), 0);
  // Segments: piercings (a stitch passes through the surface there) and candidates.
  std::vector<std::int32_t>& run_tris = scratch.run_tris;
  std::size_t run_of = ne;  // run whose union query run_tris holds
  for (std::size_t i = 0; i < ne; ++i) {
    const std::int32_t a = tm.initial.edges[i][0], b = tm.initial.edges[i][1];
    if (!cb->ThreadAlive(thread, a) || !cb->ThreadAlive(thread, b)) continue;
    const Simplex sg = SegmentSimplex(x.col(a), x.col(b));
    const Box sbox = SimplexBox(sg);
    const Box q = sbox.Inflated(reach);
    if (!q.Overlaps(bounds)) continue;
    std::vector<std::int32_t>& st = seg_tris[i];
    if (batch) {
      // One tree query per run of kRun segments (their boxes' union), filtered per segment:
      // the same ascending list as a query with q, for a fraction of the traversals.
      if (i / kRun != run_of) {
        run_of = i / kRun;
        Box u;
        for (std::size_t j = run_of * kRun; j < std::min(ne, (run_of + 1) * kRun); ++j) {
          const std::int32_t ja = tm.initial.edges[j][0], jb = tm.initial.edges[j][1];
          if (!cb->ThreadAlive(thread, ja) || !cb->ThreadAlive(thread, jb)) continue;
          u.Add(x.col(ja));
          u.Add(x.col(jb));
        }
        run_tris.clear();
        bvh.Query(u.Inflated(reach), &run_tris);
      }
      st.clear();
      for (std::int32_t t : run_tris) {
        if (bvh.TriangleBox(t).Overlaps(q)) st.push_back(t);
      }
    } else {
      query(static_cast<std::size_t>(nn) + i, q, &st);
    }
    if (st.empty()) continue;
    seg[i] = NearestOnSurface(sg, sbox, st, bvh, pos, s.local_tris, &scratch, (*hint)[nn + i]);
    if (!seg[i].found) continue;
    (*hint)[nn + i] = seg[i].tri;
    near_node[a] = near_node[b] = 1;
    if (node_seg[a] < 0) node_seg[a] = static_cast<std::int32_t>(i);
    if (node_seg[b] < 0) node_seg[b] = static_cast<std::int32_t>(i);
    // A stitch pierces tissue; nothing legitimately pierces bone, so a segment through it keeps
    // its contacts (they push it back out).
    if (seg[i].pair.dist2 == 0 && obstacle != Kind::kBone) pierced[i] = 1;
  }
  BlockAroundPiercings(tm, &scratch);
  // Nodes.
  const Box deep_bounds = bounds.Inflated(deep_reach);
  for (Eigen::Index v = 0; v < nn; ++v) {
    const std::int32_t node = static_cast<std::int32_t>(v);
    if (blocked_node[v] || !cb->ThreadAlive(thread, node) || cb->ThreadFixed(thread, node)) {
      continue;
    }
    const Simplex p = PointSimplex(x.col(v));
    const Box pbox = SimplexBox(p);
    Nearest n;
    if (near_node[v]) {
      // The node's query box lies inside its segment's: filtering that segment's candidates
      // gives exactly the triangles a query would (same overlap test, ascending).
      const Box q = pbox.Inflated(reach);
      tris.clear();
      for (std::int32_t t : seg_tris[node_seg[v]]) {
        if (bvh.TriangleBox(t).Overlaps(q)) tris.push_back(t);
      }
      n = NearestOnSurface(p, pbox, tris, bvh, pos, s.local_tris, &scratch, (*hint)[v]);
    }
    // Bone, nothing within `reach` (a triangle that near would be a candidate): the node may
    // have gone deeper; its own query out to deep_reach (cache slot v) finds the surface.
    if (deep_reach > reach && !(n.found && n.dist <= reach * (1 - 1e-6)) &&
        deep_bounds.Overlaps(pbox)) {
      query(static_cast<std::size_t>(v), pbox.Inflated(deep_reach), &tris);
      n = NearestOnSurface(p, pbox, tris, bvh, pos, s.local_tris, &scratch, (*hint)[v]);
    }
    if (n.found) (*hint)[v] = n.tri;
    if (!n.found || !InContact(n, rt, P, obstacle)) continue;
    ThreadSurfaceContact(cb, thread, ThreadPoint(thread, node, node, 0.0), n, obstacle,
                         obstacle_index, s, rt, stiffness);
  }
  SegmentInteriorContacts(cb, thread, obstacle, obstacle_index, s, pos, rt, stiffness);
}

}  // namespace

void DetectThread(ContactBuilder* cb, int t, CollisionWorld* world) {
  const CollisionParams& params = cb->params;
  for (std::size_t b = 0; b < world->soft.size(); ++b) {
    const auto& e = world->soft[b];
    ThreadSurface(cb, t, Kind::kSoftBody, static_cast<int>(b), e.surface, e.positions, e.bvh,
                  params.thread_tissue_stiffness_n_per_mm, true, &world->threads[t].soft_hint[b],
                  [&](std::size_t, const Box& q, std::vector<std::int32_t>* out) {
                    out->clear();
                    e.bvh.Query(q, out);
                  });
  }
  for (std::size_t g = 0; g < world->bones.size(); ++g) {
    const auto& e = world->bones[g];
    NearBoneCache& cache = world->threads[t].near_bone[g];
    const std::size_t slots = static_cast<std::size_t>(cb->state.threads[t].x.cols()) +
                              cb->model.threads[t].initial.edges.size();
    ResetNearBone(e.version, slots, &cache);
    ThreadSurface(cb, t, Kind::kBone, static_cast<int>(g), e.indexed, e.positions, e.bvh,
                  params.thread_bone_stiffness_n_per_mm, false, &cache.hint,
                  [&](std::size_t i, const Box& q, std::vector<std::int32_t>* out) {
                    NearBoneTriangles(e, &cache, i, q, out);
                  });
  }
}

}  // namespace arthrosim::collision::internal
