// SyncWorld: the collision surfaces and trees of the soft bodies and bones brought up to date
// with the State (refit, or rebuilt after a topology change), with their join flags and the
// salient vertices of the bones.
#include <algorithm>
#include <cmath>

#include "arthrosim/core/parallel.h"
#include "contact_internal.h"

namespace arthrosim::collision {
namespace {

using internal::FaceNormal;
using internal::FillPositions;
using internal::VertexNormal;

// True if every undirected edge of the triangles is shared by exactly two of them.
bool ClosedSurface(const std::vector<mesh::Tri>& tris) {
  std::vector<std::pair<std::int32_t, std::int32_t>> edges;
  edges.reserve(3 * tris.size());
  for (const mesh::Tri& t : tris) {
    for (int k = 0; k < 3; ++k) {
      edges.emplace_back(std::min(t[k], t[(k + 1) % 3]), std::max(t[k], t[(k + 1) % 3]));
    }
  }
  std::sort(edges.begin(), edges.end());
  for (std::size_t i = 0; i < edges.size(); i += 2) {
    if (i + 1 >= edges.size() || edges[i] != edges[i + 1] ||
        (i + 2 < edges.size() && edges[i + 2] == edges[i])) {
      return false;
    }
  }
  return !edges.empty();
}

// A bone vertex is salient when it sticks out of its neighbours' plane at a corner sharper than
// kSalientDeg between the vertex normal and an adjacent face normal: a smooth tessellated
// surface (the humeral head: ~4 degrees between faces) has none, a spur tip does. Below that,
// a tissue triangle lying on the bone is at most a sagitta L^2 / 8R away, under the skin.
constexpr double kSalientDeg = 20.0;

std::vector<std::int32_t> SalientVertices(const Surface& s, const std::vector<Vec3>& p) {
  std::vector<std::int32_t> out;
  const double cos_lim = std::cos(kSalientDeg * 3.14159265358979323846 / 180.0);
  for (std::size_t vi = 0; vi < p.size(); ++vi) {
    const std::int32_t v = static_cast<std::int32_t>(vi);
    const Vec3 vn = VertexNormal(s, p, v);
    Vec3 ring = Vec3::Zero();
    int count = 0;
    bool sharp = false;
    for (std::int32_t k = s.vertex_tri_start[v]; k < s.vertex_tri_start[v + 1]; ++k) {
      const mesh::Tri& t = s.local_tris[s.vertex_tris[k]];
      if (FaceNormal(p, t).dot(vn) < cos_lim) sharp = true;
      for (std::int32_t u : t) {
        if (u == v) continue;
        ring += p[u];
        ++count;
      }
    }
    // Convex: the vertex lies outside its neighbours' mean (a crease or pit cannot poke).
    if (sharp && count > 0 && vn.dot(p[v] - ring / count) > 0) out.push_back(v);
  }
  return out;
}

// Join flags of body b's surface against every soft body joined to it (CollisionWorld::SoftEntry
// join_vertex / join_tri): joined nodes are those coincident at rest within the join tolerance
// (as physics merges them); vertices within `band` mm of one at rest are near the join.
void JoinFlags(const Model& model, const State& state, std::size_t b, double band,
               CollisionWorld::SoftEntry* e) {
  const std::size_t nb = state.soft_bodies.size();
  e->join_vertex.assign(nb, {});
  e->join_tri.assign(nb, {});
  if (b >= model.soft_bodies.size()) return;
  const Points& xa = model.soft_bodies[b].rest_mesh.nodes;
  for (const Join& join : model.joins) {
    const int ia = model.FindSoftBody(join.body_a), ib = model.FindSoftBody(join.body_b);
    if (ia < 0 || ib < 0 || ia == ib) continue;
    const int other =
        static_cast<std::size_t>(ia) == b ? ib : (static_cast<std::size_t>(ib) == b ? ia : -1);
    if (other < 0 || static_cast<std::size_t>(other) >= nb) continue;
    const Points& xo = model.soft_bodies[other].rest_mesh.nodes;
    // Joined nodes of b: coincident with a node of `other` (sorted by x, then a window).
    std::vector<std::pair<double, std::int32_t>> sorted;
    sorted.reserve(static_cast<std::size_t>(xo.cols()));
    for (Eigen::Index k = 0; k < xo.cols(); ++k)
      sorted.emplace_back(xo(0, k), static_cast<std::int32_t>(k));
    std::sort(sorted.begin(), sorted.end());
    const double tol = join.tolerance_mm;
    std::vector<std::uint8_t> joined(static_cast<std::size_t>(xa.cols()), 0);
    std::vector<Vec3> joined_at;
    for (Eigen::Index i = 0; i < xa.cols(); ++i) {
      const Vec3 p = xa.col(i);
      auto it = std::lower_bound(sorted.begin(), sorted.end(),
                                 std::make_pair(p.x() - tol, std::int32_t{-1}));
      for (; it != sorted.end() && it->first <= p.x() + tol; ++it) {
        if ((Vec3(xo.col(it->second)) - p).norm() <= tol) {
          joined[static_cast<std::size_t>(i)] = 1;
          joined_at.push_back(p);
          break;
        }
      }
    }
    if (joined_at.empty()) continue;
    auto is_joined = [&](std::int32_t node) {
      return node >= 0 && node < static_cast<std::int32_t>(joined.size()) && joined[node] != 0;
    };
    std::vector<std::uint8_t>& jv = e->join_vertex[other];
    jv.assign(e->surface.vertices.size(), 0);
    const Points& rest = state.soft_bodies[b].x_rest;
    for (std::size_t v = 0; v < jv.size(); ++v) {
      const std::int32_t node = e->surface.vertices[v];
      const Vec3 p = node < xa.cols()
                         ? Vec3(xa.col(node))
                         : (node < rest.cols() ? Vec3(rest.col(node)) : Vec3(e->positions[v]));
      for (const Vec3& q : joined_at) {
        if ((p - q).squaredNorm() < band * band) {
          jv[v] = 1;
          break;
        }
      }
    }
    std::vector<std::uint8_t>& jt = e->join_tri[other];
    jt.assign(e->surface.tris.size(), 0);
    for (std::size_t t = 0; t < jt.size(); ++t) {
      const mesh::Tri& g = e->surface.tris[t];
      jt[t] = is_joined(g[0]) || is_joined(g[1]) || is_joined(g[2]) ? 1 : 0;
    }
  }
}

}  // namespace

void SyncWorld(const Model& model, const State& state, CollisionWorld* world) {
  world->soft.resize(state.soft_bodies.size());
  for (std::size_t b = 0; b < state.soft_bodies.size(); ++b) {
    const SoftBodyState& sb = state.soft_bodies[b];
    CollisionWorld::SoftEntry& e = world->soft[b];
    if (!e.built || e.tet_count != sb.tets.size() || e.alive != sb.tet_alive) {
      e.surface = MakeSurface(BoundaryTriangles(sb.tets, sb.tet_alive));
      e.tet_count = sb.tets.size();
      e.alive = sb.tet_alive;
      FillPositions(sb.x, e.surface.vertices, &e.positions);
      e.bvh.Build(e.positions, e.surface.local_tris);
      e.built = true;
      e.near_bone.clear();
      e.fixed.assign(e.surface.vertices.size(), 0);
      if (b < model.soft_bodies.size()) {
        const auto& f = model.soft_bodies[b].fixed_nodes;
        for (std::size_t v = 0; v < e.surface.vertices.size(); ++v) {
          e.fixed[v] = std::binary_search(f.begin(), f.end(), e.surface.vertices[v]) ? 1 : 0;
        }
      }
      JoinFlags(model, state, b, model.contact.alarm_distance_mm + model.contact.max_depth_mm, &e);
      ++e.version;
      e.drift_mm = 0;
      ++world->rebuilds;
      e.refit_pending = false;
    } else {
      e.refit_pending = true;
    }
  }
  // Refit the others, and each surface's drift (largest vertex move) for the out-of-reach
  // bounds: independent per body.
  ParallelFor(static_cast<std::int64_t>(state.soft_bodies.size()), 1,
              [&](std::int64_t begin, std::int64_t end) {
                for (std::int64_t b = begin; b < end; ++b) {
                  CollisionWorld::SoftEntry& e = world->soft[static_cast<std::size_t>(b)];
                  if (!e.refit_pending) continue;
                  const Points& x = state.soft_bodies[static_cast<std::size_t>(b)].x;
                  double move2 = 0;
                  for (std::size_t i = 0; i < e.surface.vertices.size(); ++i) {
                    const Vec3 q = x.col(e.surface.vertices[i]);
                    move2 = std::max(move2, (q - e.positions[i]).squaredNorm());
                    e.positions[i] = q;
                  }
                  e.drift_mm += std::sqrt(move2);
                  e.bvh.Refit(e.positions);
                  e.refit_pending = false;
                }
              });
  world->bones.resize(state.bones.size());
  for (std::size_t g = 0; g < state.bones.size(); ++g) {
    const mesh::TriMesh& m = state.bones[g].surface;
    CollisionWorld::BoneEntry& e = world->bones[g];
    // Bone surfaces change only through code that increments their revision; the sizes are a
    // cheap second check. (A bitwise comparison of both surfaces cost ~10% of the stage.)
    const bool same = e.built && e.revision == state.bones[g].revision &&
                      e.surface.nodes.cols() == m.nodes.cols() &&
                      e.surface.tris.size() == m.tris.size();
    if (same) continue;
    e.revision = state.bones[g].revision;
    e.surface = m;
    e.indexed = MakeSurface(CanonicalTriangles(m.tris));
    FillPositions(m.nodes, e.indexed.vertices, &e.positions);
    e.bvh.Build(e.positions, e.indexed.local_tris);
    e.closed = ClosedSurface(e.indexed.tris);
    e.salient = SalientVertices(e.indexed, e.positions);
    e.built = true;
    ++e.version;
    ++world->rebuilds;
  }
  for (CollisionWorld::SoftEntry& e : world->soft) {
    e.near_bone.resize(world->bones.size());
    e.far_soft.resize(world->soft.size());
  }
  for (CollisionWorld::BoneEntry& e : world->bones) e.far_soft.resize(world->soft.size());
  world->threads.resize(state.threads.size());
  for (CollisionWorld::ThreadEntry& e : world->threads) {
    e.near_bone.resize(world->bones.size());
    e.soft_hint.resize(world->soft.size());
  }
}

}  // namespace arthrosim::collision
