// Collision stage, tool slot task: the slot's primitives swept from last step's pose to this
// step's against soft tissue (surface points, and the volume a sharp point enters), threads and
// bone (a reaction on the kinematic tool only).
#include <algorithm>
#include <cmath>
#include <span>

#include "contact_internal.h"

namespace arthrosim::collision::internal {
namespace {

// ---- tool against soft tissue -------------------------------------------------------------

void ToolTissue(ContactBuilder* cb, int slot, const Sweep& sw, int body,
                CollisionWorld::SoftEntry& e) {
  const CollisionParams& P = cb->params;
  const double r = sw.prim->radius_mm;
  const double reach = r + P.alarm_distance_mm;
  const Box query = sw.box.Inflated(reach);
  if (e.bvh.empty() || !query.Overlaps(e.bvh.Bounds())) return;
  std::vector<std::int32_t>& tris = cb->scratch.tris;
  std::vector<std::int32_t>& verts = cb->scratch.verts;
  tris.clear();
  verts.clear();
  // Sized for the whole surface once, so a bigger overlap later does not allocate.
  tris.reserve(e.surface.local_tris.size());
  verts.reserve(3 * e.surface.local_tris.size());
  // Triangles that may come within reach of the core at some substep (every vertex within reach
  // is a corner of one of them).
  e.bvh.QueryIf([&](const Box& b) { return SweepNear(sw, reach, b); }, &tris);
  for (std::int32_t t : tris) {
    for (std::int32_t v : e.surface.local_tris[t]) verts.push_back(v);
  }
  std::sort(verts.begin(), verts.end());
  verts.erase(std::unique(verts.begin(), verts.end()), verts.end());
  auto make = [&](const ClosestPair& touch, const ClosestPair& cur, const Vec3& fallback) {
    PointContact c;
    c.target = PointContact::Target::kSoftBody;
    c.index = body;
    // Direction fixed where the point first came within reach (outside the core, as the sweep
    // substep is below the alarm distance); the plane is this step's tangent plane of the tool
    // with that normal (support of the core), so the point is pushed ahead of the whole part
    // even where the core has passed it (a needle point through a triangle).
    (void)cur;
    c.normal = SafeNormalized(touch.pb - touch.pa, fallback);
    c.offset_mm = Support(sw.sub.back(), c.normal) + r + P.contact_distance_mm;
    c.stiffness_n_per_mm = P.tool_tissue_stiffness_n_per_mm;
    c.tool_slot = slot;
    c.obstacle_id = -1;
    return c;
  };
  // A blade slides in its own cut. The faces a split-mode cut makes lie in the blade's plane:
  // the cutting edge meets them edge-on and the closing blade then holds them inside its
  // thickness, where pressing them (no meaningful direction there) crushes the thin pieces
  // beside the cut and inverts them (docs/operations.md, Scissors). So a blade never pushes a
  // point of a cut surface, one with a node made by a split (the other parts of the instrument,
  // e.g. the shaft entering the cut, still do). Remove mode makes no nodes: unchanged.
  const bool blade = sw.prim->part == ToolPart::kBlade;
  auto on_cut_surface = [&](std::span<const std::int32_t> nodes) {
    return blade && std::any_of(nodes.begin(), nodes.end(),
                                [&](std::int32_t n) { return cb->MadeByCut(body, n); });
  };
  // 1. Surface vertices.
  for (std::int32_t v : verts) {
    const std::int32_t node = e.surface.vertices[v];
    const Vec3& p = e.positions[v];
    if ((p.array() < query.lo.array()).any() || (p.array() > query.hi.array()).any()) continue;
    if (cb->SoftFixed(body, node) || on_cut_surface({&node, 1})) continue;
    ClosestPair touch;
    const int at = FirstTouch(sw, reach, PointSimplex(p), Box{p, p}, &touch);
    if (at < 0) continue;
    const ClosestPair cur = CurrentClosest(sw, at, touch, PointSimplex(p));
    PointContact c = make(touch, cur, -VertexNormal(e.surface, e.positions, v));
    c.nodes = {node, -1, -1, -1};
    c.weights = {1, 0, 0, 0};
    cb->Add(c, Kind::kTool);
  }
  // 2. Surface points between vertices: for each triangle within reach whose nearest point to
  // the tool is inside it or on an edge, a contact there, so a sharp or small part (blade edge,
  // awl point) cannot slip between vertices. Edge points are shared by two triangles: the first
  // (lowest canonical triangle) keeps it.
  std::vector<std::pair<std::int32_t, std::int32_t>>& edges_done = cb->scratch.edges_done;
  edges_done.clear();
  for (std::int32_t t : tris) {
    const mesh::Tri& g = e.surface.tris[t];
    if (cb->SoftFixed(body, g[0]) && cb->SoftFixed(body, g[1]) && cb->SoftFixed(body, g[2]))
      continue;
    if (on_cut_surface(g)) continue;
    const Simplex tri = LocalTriangle(e.positions, e.surface.local_tris[t]);
    // The current closest point first: at a vertex there is nothing to add (often the case),
    // and the last substep of the touch search is then known.
    if (!MayTouch(sw, reach, tri, e.bvh.TriangleBox(t))) continue;
    const ClosestPair cur = Closest(sw.sub.back(), tri);
    const auto& w = cur.wb;
    const int zeros = (w[0] <= 0) + (w[1] <= 0) + (w[2] <= 0);
    if (zeros >= 2) continue;  // at a vertex: the vertex contact covers it
    ClosestPair touch;
    if (FirstTouch(sw, reach, tri, e.bvh.TriangleBox(t), &touch, &cur) < 0) continue;
    if (zeros == 1) {
      const int k = w[0] <= 0 ? 0 : (w[1] <= 0 ? 1 : 2);
      const std::pair<std::int32_t, std::int32_t> edge{std::min(g[(k + 1) % 3], g[(k + 2) % 3]),
                                                       std::max(g[(k + 1) % 3], g[(k + 2) % 3])};
      if (std::find(edges_done.begin(), edges_done.end(), edge) != edges_done.end()) continue;
      edges_done.push_back(edge);
    }
    PointContact c = make(touch, cur, -FaceNormal(e.positions, e.surface.local_tris[t]));
    c.nodes = {g[0], g[1], g[2], -1};
    c.weights = {w[0], w[1], w[2], 0};
    cb->Add(c, Kind::kTool);
  }
}

// ---- sharp tool point inside the tissue volume ---------------------------------------------

// Barycentric weights of p in tet (a, b, c, d); false if the tet is degenerate.
bool TetWeights(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d,
                std::array<double, 4>* w) {
  Eigen::Matrix3d m;
  m.col(0) = b - a;
  m.col(1) = c - a;
  m.col(2) = d - a;
  const double det = m.determinant();
  if (!(std::abs(det) > 1e-15)) return false;
  const Vec3 l = m.inverse() * (p - a);
  *w = {1 - l[0] - l[1] - l[2], l[0], l[1], l[2]};
  return true;
}

// A sharp point (the end v0 of an awl-point core) is held at tissue vertices and at one point
// per surface triangle; on coarse tissue the tented triangles around it fold and slide off
// sideways. So the material the point has gone through in this step is held too: each sweep
// substep position of the point that lies inside an alive tet (deformed, at t_n) gives a contact
// on that material point (the tet's four nodes, barycentric weights) pushing it ahead of the
// point along the part's axis, to the plane through the current point + radius + skin. The
// axis, not the surface normal, so a tented apex cannot be pushed sideways, and one-sided, so
// retracting the point releases the material.
void ToolVolume(ContactBuilder* cb, int slot, const Sweep& sw, int body, const SoftBodyState& sb,
                const CollisionWorld::SoftEntry& e) {
  const CollisionParams& P = cb->params;
  if (!P.sharp_point_volume_contacts || sw.prim->part != ToolPart::kAwlTip || sw.sub.back().n < 2) {
    return;
  }
  const Simplex& now = sw.sub.back();
  const Vec3 axis = SafeNormalized(now.v[0] - now.v[1], Vec3::UnitZ());
  const double reach = sw.prim->radius_mm + P.contact_distance_mm;
  // Material points: the point's position at each substep (what it went through this step) and
  // points ahead of it up to the alarm distance beyond its surface (what it may reach during the
  // solve: contacts exist before touching, as everywhere else).
  std::vector<Vec3>& pts = cb->scratch.points;
  pts.clear();
  for (const Simplex& s : sw.sub) pts.push_back(s.v[0]);
  const double ahead = reach + P.alarm_distance_mm;
  const int n_ahead = static_cast<int>(std::ceil(ahead / (P.sweep_fraction * P.alarm_distance_mm)));
  for (int j = 1; j <= n_ahead; ++j) pts.push_back(now.v[0] + (ahead * j / n_ahead) * axis);
  Box path;
  for (const Vec3& p : pts) path.Add(p);
  if (e.bvh.empty() || !path.Overlaps(e.bvh.Bounds())) return;
  // Four planes tilted toward the axis by atan(kEngage) (a pyramid ahead of the point): at the
  // axis each asks for `reach` ahead of the core end; a material point that slides sideways by l
  // must be kEngage * l further ahead, so it is pushed back toward the axis (the point has
  // engaged it, like friction mu = kEngage) instead of sliding off.
  constexpr double kEngage = 1.0;
  const double inv_len = 1 / std::sqrt(1 + kEngage * kEngage);
  const Vec3 e1 = axis.unitOrthogonal(), e2 = axis.cross(e1);
  const std::array<Vec3, 4> lateral{e1, -e1, e2, -e2};
  const std::size_t nsub = pts.size();
  std::vector<std::int32_t>& owner = cb->scratch.owner;  // first tet holding each point
  std::vector<std::array<double, 4>>& weights = cb->scratch.weights;
  owner.assign(nsub, -1);
  weights.assign(nsub, {0, 0, 0, 0});
  for (std::size_t t = 0; t < sb.tets.size(); ++t) {
    if (t < sb.tet_alive.size() && !sb.tet_alive[t]) continue;
    const mesh::Tet& tet = sb.tets[t];
    Box tb;
    for (std::int32_t n : tet) tb.Add(sb.x.col(n));
    if (!tb.Overlaps(path)) continue;
    for (std::size_t s = 0; s < nsub; ++s) {
      const Vec3& p = pts[s];
      if (owner[s] >= 0 || !tb.Overlaps(Box{p, p})) continue;
      std::array<double, 4> w;
      if (!TetWeights(p, sb.x.col(tet[0]), sb.x.col(tet[1]), sb.x.col(tet[2]), sb.x.col(tet[3]),
                      &w)) {
        continue;
      }
      if (*std::min_element(w.begin(), w.end()) < 0) continue;
      owner[s] = static_cast<std::int32_t>(t);
      weights[s] = w;
    }
  }
  auto engage = [&](const std::array<std::int32_t, 4>& nodes, const std::array<double, 4>& w) {
    for (const Vec3& side : lateral) {
      PointContact c;
      c.target = PointContact::Target::kSoftBody;
      c.index = body;
      c.nodes = nodes;
      c.weights = w;
      c.normal = (axis - kEngage * side) * inv_len;
      c.offset_mm = c.normal.dot(now.v[0]) + reach * inv_len;
      c.stiffness_n_per_mm = P.tool_volume_stiffness_n_per_mm;
      c.tool_slot = slot;
      cb->Add(c, Kind::kTool);
    }
  };
  for (std::size_t s = 0; s < nsub; ++s) {
    if (owner[s] < 0) continue;
    const mesh::Tet& tet = sb.tets[owner[s]];
    if (cb->SoftFixed(body, tet[0]) && cb->SoftFixed(body, tet[1]) && cb->SoftFixed(body, tet[2]) &&
        cb->SoftFixed(body, tet[3])) {
      continue;
    }
    engage({tet[0], tet[1], tet[2], tet[3]}, weights[s]);
  }
  // Surface points on the point's path: where the segment from last step's point to `ahead`
  // beyond the current one crosses a boundary triangle (a thin membrane's far surface, which a
  // coarse tet may not hold in front of the point once it is squeezed).
  const Vec3 from = sw.sub.front().v[0], to = pts.back();
  const Vec3 dir = to - from;
  std::vector<std::int32_t>& tris = cb->scratch.tris;
  tris.clear();
  Box seg;
  seg.Add(from);
  seg.Add(to);
  e.bvh.Query(seg, &tris);
  for (std::int32_t t : tris) {
    const mesh::Tri& g = e.surface.tris[t];
    const mesh::Tri& l = e.surface.local_tris[t];
    const Vec3 a = e.positions[l[0]], b = e.positions[l[1]], c = e.positions[l[2]];
    const Vec3 ab = b - a, ac = c - a, pv = dir.cross(ac);
    const double det = ab.dot(pv);
    if (!(std::abs(det) > 1e-15)) continue;  // parallel: the volume points hold it
    const Vec3 tv = from - a;
    const double u = tv.dot(pv) / det;
    const Vec3 qv = tv.cross(ab);
    const double v = dir.dot(qv) / det, f = ac.dot(qv) / det;
    if (u < 0 || v < 0 || u + v > 1 || f < 0 || f > 1) continue;
    if (cb->SoftFixed(body, g[0]) && cb->SoftFixed(body, g[1]) && cb->SoftFixed(body, g[2]))
      continue;
    engage({g[0], g[1], g[2], -1}, {1 - u - v, u, v, 0});
  }
}

// ---- tool against thread ------------------------------------------------------------------

void ToolThread(ContactBuilder* cb, int slot, const Sweep& sw, int thread,
                const ThreadBoxes& boxes) {
  const CollisionParams& P = cb->params;
  const ThreadModel& tm = cb->model.threads[thread];
  const Points& x = cb->state.threads[thread].x;
  const double rt = 0.5 * tm.diameter_mm;
  const double r = sw.prim->radius_mm;
  const double reach = r + rt + P.alarm_distance_mm;
  const std::size_t ne = tm.initial.edges.size();
  const std::vector<Box>& seg_box = boxes.seg;
  const std::vector<Box>& run_box = boxes.run;
  std::int32_t last_single = -1;  // a node already given a contact by the previous segment
  for (std::size_t i = 0; i < ne; ++i) {
    if (i % kRun == 0 && (run_box[i / kRun].Empty() || !SweepNear(sw, reach, run_box[i / kRun]))) {
      i += kRun - 1;
      continue;
    }
    const std::int32_t a = tm.initial.edges[i][0], b = tm.initial.edges[i][1];
    if (seg_box[i].Empty() || !SweepNear(sw, reach, seg_box[i])) continue;
    const Simplex seg = SegmentSimplex(x.col(a), x.col(b));
    ClosestPair touch;
    const int at = FirstTouch(sw, reach, seg, seg_box[i], &touch);
    if (at < 0) continue;
    const ClosestPair cur = CurrentClosest(sw, at, touch, seg);
    PointContact c = ThreadPoint(thread, a, b, cur.wb[1]);
    if (c.nodes[1] < 0) {
      if (c.nodes[0] == last_single) continue;
      last_single = c.nodes[0];
    }
    if (cb->ThreadFixed(thread, c.nodes[0]) &&
        (c.nodes[1] < 0 || cb->ThreadFixed(thread, c.nodes[1]))) {
      continue;
    }
    const Vec3 motion = sw.sub.back().At(touch.wa) - sw.sub.front().At(touch.wa);
    c.normal = SafeNormalized(touch.pb - touch.pa, SafeNormalized(motion, Vec3::UnitZ()));
    c.offset_mm = Support(sw.sub.back(), c.normal) + r + rt + P.contact_distance_mm;
    c.stiffness_n_per_mm = P.tool_thread_stiffness_n_per_mm;
    c.tool_slot = slot;
    cb->Add(c, Kind::kTool);
  }
}

// ---- tool against bone: reaction on the kinematic tool only --------------------------------

void ToolBone(ContactBuilder* cb, int slot, const Sweep& sw, CollisionWorld::BoneEntry& e,
              CollisionOutput* out, double* deepest, Vec3* deepest_point) {
  const double r = sw.prim->radius_mm;
  const Simplex& now = sw.sub.back();
  const double reach = r + cb->params.contact_distance_mm;
  const Box now_box = SimplexBox(now);
  if (e.bvh.empty() || !NearBoxes(now_box, reach, e.bvh.Bounds())) return;
  std::vector<std::int32_t>& tris = cb->scratch.tris;
  tris.clear();
  // Only triangles that may be within reach of the core: the nearest one when there is a
  // penetration (and all its equally near neighbours) are among them.
  e.bvh.QueryIf([&](const Box& b) { return BoxNearCore(now_box, now, reach, b); }, &tris);
  const Nearest n =
      NearestOnSurface(now, now_box, tris, e.bvh, e.positions, e.indexed.local_tris, &cb->scratch);
  if (!n.found) return;
  const double depth = r - n.Signed();
  if (depth <= 0) return;
  const Vec3 dir = n.Signed() > kMinDirection ? Vec3((n.pair.pa - n.pair.pb) / n.dist) : n.pseudo;
  out->bone_force_n[slot] += cb->params.tool_bone_stiffness_n_per_mm * depth * dir;
  if (depth > *deepest) {
    *deepest = depth;
    *deepest_point = n.pair.pb;
  }
}

// Fills the first entries of *sweeps (reusing their storage) with the swept contact parts of one
// tool slot and returns how many; *prims and *before receive this step's and last step's
// primitives (sweeps point into *prims).
std::size_t MakeSweeps(const Model& model, const ToolState& prev, const ToolState& cur,
                       const CollisionParams& params, std::vector<ToolPrimitive>* prims,
                       std::vector<ToolPrimitive>* before, std::vector<Sweep>* sweeps,
                       std::int32_t* substeps) {
  ToolPrimitivesWorld(model, cur, prims);
  if (prev.instrument == cur.instrument) {
    ToolPrimitivesWorld(model, prev, before);
  } else {
    before->assign(prims->begin(), prims->end());
  }
  double disp = 0;
  for (std::size_t j = 0; j < prims->size(); ++j) {
    for (int i = 0; i < (*prims)[j].core.n; ++i) {
      disp = std::max(disp, ((*prims)[j].core.v[i] - (*before)[j].core.v[i]).norm());
    }
  }
  const double step = params.sweep_fraction * params.alarm_distance_mm;
  const int k = std::clamp(static_cast<int>(std::ceil(disp / step)), 1, params.max_substeps);
  *substeps = k;
  std::size_t used = 0;
  for (std::size_t j = 0; j < prims->size(); ++j) {
    if (!(*prims)[j].contacts) continue;
    if (sweeps->size() <= used) {
      sweeps->emplace_back();  // sized once for the largest substep count
      sweeps->back().sub.reserve(static_cast<std::size_t>(params.max_substeps) + 1);
      sweeps->back().sub_box.reserve(static_cast<std::size_t>(params.max_substeps) + 1);
    }
    Sweep& sw = (*sweeps)[used++];
    sw.prim = &(*prims)[j];
    sw.sub.clear();
    sw.sub_box.clear();
    sw.box = Box{};
    for (int s = 0; s <= k; ++s) {
      Simplex core = (*prims)[j].core;
      if (s < k) {
        const double f = static_cast<double>(s) / k;
        for (int i = 0; i < core.n; ++i) {
          core.v[i] = (*before)[j].core.v[i] + f * ((*prims)[j].core.v[i] - (*before)[j].core.v[i]);
        }
      }
      Box core_box;
      for (int i = 0; i < core.n; ++i) core_box.Add(core.v[i]);
      sw.box.Add(core_box.lo);
      sw.box.Add(core_box.hi);
      sw.sub.push_back(core);
      sw.sub_box.push_back(core_box);
    }
  }
  // Entries past `used` are kept (with their storage) for later steps, not destroyed.
  return used;
}

}  // namespace

void MakeThreadBoxes(const Model& model, const State& state, int thread, ThreadBoxes* out) {
  const ThreadModel& tm = model.threads[thread];
  const Points& x = state.threads[thread].x;
  const auto& alive = state.threads[thread].node_alive;
  auto is_alive = [&](std::int32_t node) {
    return node < static_cast<std::int32_t>(alive.size()) && alive[node] != 0;
  };
  const std::size_t ne = tm.initial.edges.size();
  out->seg.assign(ne, Box{});
  out->run.assign((ne + kRun - 1) / kRun, Box{});
  for (std::size_t i = 0; i < ne; ++i) {
    const std::int32_t a = tm.initial.edges[i][0], b = tm.initial.edges[i][1];
    if (!is_alive(a) || !is_alive(b)) continue;
    out->seg[i].Add(x.col(a));
    out->seg[i].Add(x.col(b));
    out->run[i / kRun].Add(x.col(a));
    out->run[i / kRun].Add(x.col(b));
  }
}

void DetectToolSlot(ContactBuilder* cb, int slot,
                    const std::array<ToolState, kToolSlots>& prev_tools, CollisionWorld* world,
                    const std::vector<ThreadBoxes>& thread_boxes, CollisionOutput* out) {
  const Model& model = cb->model;
  const State& state = cb->state;
  ContactTaskScratch& scratch = cb->scratch;
  out->substeps[slot] = 0;
  const std::size_t used =
      MakeSweeps(model, prev_tools[slot], state.tools[slot], cb->params, &scratch.prims,
                 &scratch.before, &scratch.sweeps, &out->substeps[slot]);
  const std::span<const Sweep> sweeps(scratch.sweeps.data(), used);
  for (std::size_t b = 0; b < world->soft.size(); ++b) {
    for (const Sweep& sw : sweeps) {
      ToolTissue(cb, slot, sw, static_cast<int>(b), world->soft[b]);
      ToolVolume(cb, slot, sw, static_cast<int>(b), state.soft_bodies[b], world->soft[b]);
    }
  }
  if (!sweeps.empty()) {
    for (std::size_t t = 0; t < state.threads.size(); ++t) {
      for (const Sweep& sw : sweeps) ToolThread(cb, slot, sw, static_cast<int>(t), thread_boxes[t]);
    }
  }
  for (std::size_t g = 0; g < world->bones.size(); ++g) {
    double deepest = 0;
    Vec3 point = Vec3::Zero();
    for (const Sweep& sw : sweeps) {
      ToolBone(cb, slot, sw, world->bones[g], out, &deepest, &point);
    }
    if (deepest > 0) {
      scratch.touches.push_back(ToolContact{slot, Kind::kBone, static_cast<int>(g), point});
    }
  }
}

}  // namespace arthrosim::collision::internal
