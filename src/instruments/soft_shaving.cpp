// Shaver and electrocautery on muscle and tendon (Choi et al. 2020, section III.2).
#include "arthrosim/instruments/soft_shaving.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>

#include "arthrosim/collision/instrument_shape.h"
#include "arthrosim/instruments/cutting.h"

namespace arthrosim::instruments {
namespace {

// Local index of global node `node` on a collision surface, or -1.
std::int32_t LocalVertex(const collision::Surface& s, std::int32_t node) {
  const auto it = std::lower_bound(s.vertices.begin(), s.vertices.end(), node);
  if (it == s.vertices.end() || *it != node) return -1;
  return static_cast<std::int32_t>(it - s.vertices.begin());
}

// Outward area-weighted normal of local surface vertex v at positions x (global node ids).
Vec3 OutwardNormal(const collision::Surface& s, const Points& x, std::int32_t v) {
  Vec3 n = Vec3::Zero();
  for (std::int32_t k = s.vertex_tri_start[static_cast<std::size_t>(v)];
       k < s.vertex_tri_start[static_cast<std::size_t>(v) + 1]; ++k) {
    const mesh::Tri& t =
        s.tris[static_cast<std::size_t>(s.vertex_tris[static_cast<std::size_t>(k)])];
    n += (x.col(t[1]) - x.col(t[0])).cross(x.col(t[2]) - x.col(t[0]));
  }
  const double len = n.norm();
  return len > 0 ? Vec3(n / len) : Vec3::Zero();
}

double SignedVolume(const Points& p, const mesh::Tet& t) {
  const Vec3 p0 = p.col(t[0]);
  return (p.col(t[1]) - p0).dot((p.col(t[2]) - p0).cross(p.col(t[3]) - p0)) / 6.0;
}

std::string Number(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.9g", v);
  return buf;
}

// True when alive tet `self` of the body hangs on the rest of it by an edge, a vertex or
// nothing: at most two of its nodes belong to another alive tet or to a joined interface. Such a
// tet turns freely about that edge or vertex (three held nodes pin it: a tet whose faces are all
// free but whose four corners are held is not loose).
bool HangsLoose(const SoftBodyState& sb, const physics::SoftSystem& soft, int body,
                std::int32_t self) {
  const mesh::Tet& e = sb.tets[static_cast<std::size_t>(self)];
  int held = 0;
  for (const std::int32_t n : e) {
    bool shared = soft.IsJoined(body, n);
    for (std::size_t t = 0; t < sb.tets.size() && !shared; ++t) {
      if (!sb.tet_alive[t] || static_cast<std::int32_t>(t) == self) continue;
      const mesh::Tet& o = sb.tets[t];
      shared = std::find(o.begin(), o.end(), n) != o.end();
    }
    held += shared ? 1 : 0;
  }
  return held <= 2;
}

const collision::ToolPrimitive* FindPart(const std::vector<collision::ToolPrimitive>& prims,
                                         collision::ToolPart part) {
  for (const collision::ToolPrimitive& p : prims) {
    if (p.part == part) return &p;
  }
  return nullptr;
}

void ShaveWith(const Model& model, int slot, collision::ToolPart part,
               const SoftShavingOptions& opt, bool cauterize, const char* kind,
               const StepContext& context, State* state, InstrumentScratch* scratch) {
  const ToolState& tool = state->tools[static_cast<std::size_t>(slot)];
  if (!Button1(tool) || context.world == nullptr || context.soft == nullptr) return;
  std::vector<collision::ToolPrimitive>& prims = scratch->primitives;
  collision::ToolPrimitivesWorld(model, tool, &prims);
  const collision::ToolPrimitive* tip = FindPart(prims, part);
  if (tip == nullptr) return;
  // Table 1: shaver and electrocautery act on muscle and tendon, i.e. the soft bodies (the
  // anatomic scene's subacromial bursa is one: they debride it as they do muscle and tendon).
  for (std::size_t b = 0; b < state->soft_bodies.size(); ++b) {
    const ShaveResult r = ShaveBody(model, slot, static_cast<int>(b), tip->core, tip->radius_mm,
                                    opt, cauterize, context, state, scratch);
    if (r.moved_nodes == 0) continue;
    RecordEvent(model, slot, kind, model.soft_bodies[b].name,
                "nodes=" + std::to_string(r.moved_nodes) +
                    " smoothed=" + std::to_string(r.smoothed_nodes) + " removed_tets=" +
                    std::to_string(r.removed_tets) + " volume_mm3=" + Number(r.volume_mm3),
                r.centre_mm, state);
  }
}

}  // namespace

ShaveResult ShaveBody(const Model& model, int slot, int body, const collision::Simplex& core,
                      double radius_mm, const SoftShavingOptions& opt, bool cauterize,
                      const StepContext& context, State* state, InstrumentScratch* scratch) {
  ShaveResult result;
  const auto bi = static_cast<std::size_t>(body);
  if (context.contacts == nullptr || bi >= context.world->soft.size()) return result;
  const collision::Surface& surf = context.world->soft[bi].surface;
  SoftBodyState& sb = state->soft_bodies[bi];
  physics::SoftSystem& soft = *context.soft;
  // 1. Touched vertices: free, unjoined surface nodes this slot's contacts name, within reach.
  std::vector<std::int32_t>& touched = scratch->nodes;
  touched.clear();
  const double reach = radius_mm + opt.reach_mm;
  for (const physics::PointContact& c : context.contacts->contacts) {
    if (c.tool_slot != slot || c.target != physics::PointContact::Target::kSoftBody ||
        c.index != body)
      continue;
    for (std::int32_t n : c.nodes) {
      if (n < 0 || !soft.IsFree(body, n)) continue;
      const physics::NodeRef own = soft.Owner(body, n);
      if (own.body != body || own.node != n) continue;  // joined copy: its owner is shaved
      if (LocalVertex(surf, n) < 0) continue;
      const collision::ClosestPair p =
          collision::Closest(collision::PointSimplex(sb.x.col(n)), core);
      if (p.dist2 <= reach * reach) touched.push_back(n);
    }
  }
  std::sort(touched.begin(), touched.end());
  touched.erase(std::unique(touched.begin(), touched.end()), touched.end());
  if (touched.empty()) return result;

  // 2. Inward moves: depth rate * dt along the outward normal for touched vertices; ring
  // neighbours get `smoothing` times the mean move of their touched neighbours.
  const double depth = opt.rate_mm_s * model.options.dt_s;
  std::vector<std::int32_t> moved = touched;
  std::vector<Vec3> delta;
  delta.reserve(touched.size());
  for (std::int32_t n : touched) {
    delta.push_back(-depth * OutwardNormal(surf, sb.x, LocalVertex(surf, n)));
    result.centre_mm += sb.x.col(n);
  }
  result.centre_mm /= static_cast<double>(touched.size());
  result.moved_nodes = static_cast<int>(touched.size());
  std::vector<std::pair<std::int32_t, Vec3>> ring;  // (neighbour, summed move) pairs
  std::vector<std::pair<std::int32_t, int>> ring_count;
  for (std::size_t i = 0; i < touched.size(); ++i) {
    const std::int32_t v = LocalVertex(surf, touched[i]);
    for (std::int32_t k = surf.vertex_tri_start[static_cast<std::size_t>(v)];
         k < surf.vertex_tri_start[static_cast<std::size_t>(v) + 1]; ++k) {
      for (std::int32_t u :
           surf.tris[static_cast<std::size_t>(surf.vertex_tris[static_cast<std::size_t>(k)])]) {
        if (std::binary_search(touched.begin(), touched.end(), u)) continue;
        ring.emplace_back(u, delta[i]);
      }
    }
  }
  std::sort(ring.begin(), ring.end(),
            [](const auto& a, const auto& b) { return a.first < b.first; });  // stable ids
  for (std::size_t i = 0; i < ring.size();) {
    std::size_t j = i;
    Vec3 sum = Vec3::Zero();
    for (; j < ring.size() && ring[j].first == ring[i].first; ++j) sum += ring[j].second;
    const std::int32_t u = ring[i].first;
    const physics::NodeRef own = soft.Owner(body, u);
    if (soft.IsFree(body, u) && own.body == body && own.node == u) {
      moved.push_back(u);
      delta.push_back(opt.smoothing * sum / static_cast<double>(j - i));
      ++result.smoothed_nodes;
    }
    i = j;
  }

  // 3. Elements around the moved nodes (through the element tree), before the move.
  scratch->tet_trees.resize(state->soft_bodies.size());
  collision::TetTree& tree = scratch->tet_trees[bi];
  if (!tree.BuiltFor(sb.tets.size())) {
    tree.Build(sb.x, sb.tets);
  } else {
    tree.Refit(sb.x, sb.tets);
  }
  collision::Box box;
  for (std::int32_t n : moved) box.Add(sb.x.col(n));
  std::vector<std::int32_t>& tets = scratch->tets;
  tree.QueryBox(sb.tet_alive, box, &tets);
  std::vector<std::int32_t> sorted_moved = moved;
  std::sort(sorted_moved.begin(), sorted_moved.end());
  tets.erase(std::remove_if(tets.begin(), tets.end(),
                            [&](std::int32_t t) {
                              for (std::int32_t n : sb.tets[static_cast<std::size_t>(t)]) {
                                if (std::binary_search(sorted_moved.begin(), sorted_moved.end(), n))
                                  return false;
                              }
                              return true;
                            }),
             tets.end());
  double before = 0;
  for (std::int32_t t : tets)
    before += SignedVolume(sb.x_rest, sb.tets[static_cast<std::size_t>(t)]);

  // 4. Move current and rest positions (plastic), refresh the touched elements' rest data.
  Points rest(3, static_cast<Eigen::Index>(moved.size()));
  for (std::size_t i = 0; i < moved.size(); ++i) {
    const auto c = static_cast<Eigen::Index>(i);
    rest.col(c) = sb.x_rest.col(moved[i]) + delta[i];
    sb.x.col(moved[i]) += delta[i];
  }
  soft.SetRestPositions(body, moved, rest, state);

  // 5. Elements thinner than min_volume_fraction of their initial rest volume, or inverted in
  // the current configuration, are removed.
  const SoftBodyModel& bm = model.soft_bodies[bi];
  std::vector<std::int32_t> thin;
  double after = 0;
  for (std::int32_t t : tets) {
    const mesh::Tet& e = sb.tets[static_cast<std::size_t>(t)];
    const double v_rest = SignedVolume(sb.x_rest, e);
    const double v_initial =
        static_cast<std::size_t>(t) < bm.rest_mesh.tets.size()
            ? SignedVolume(bm.rest_mesh.nodes, bm.rest_mesh.tets[static_cast<std::size_t>(t)])
            : v_rest;
    if (v_rest <= opt.min_volume_fraction * v_initial || SignedVolume(sb.x, e) <= 0) {
      thin.push_back(t);
    } else {
      after += v_rest;
    }
  }
  soft.RemoveTets(body, thin, state);
  result.removed_tets = static_cast<int>(thin.size());

  // 6. Debris: an alive element left hanging by an edge or a vertex (HangsLoose) is a mechanism
  // the corotational step cannot hold (its rotation, taken at the step's start, lags the flapping
  // element: in the economy trainee's run such a tet of the tendon rang for 50 s and then
  // diverged). It goes with the shave, as the shaver's suction takes a loose shred; removing it
  // can loosen another, hence the loop.
  double debris_volume = 0;
  std::vector<std::int32_t> frontier = thin;
  while (!frontier.empty()) {
    std::vector<std::int32_t> near;
    for (std::int32_t t : frontier) {
      const mesh::Tet& e = sb.tets[static_cast<std::size_t>(t)];
      near.insert(near.end(), e.begin(), e.end());
    }
    std::sort(near.begin(), near.end());
    near.erase(std::unique(near.begin(), near.end()), near.end());
    std::vector<std::int32_t> debris;
    for (std::size_t t = 0; t < sb.tets.size(); ++t) {
      if (!sb.tet_alive[t]) continue;
      const mesh::Tet& e = sb.tets[t];
      const bool touches = std::any_of(e.begin(), e.end(), [&](std::int32_t n) {
        return std::binary_search(near.begin(), near.end(), n);
      });
      if (touches && HangsLoose(sb, soft, body, static_cast<std::int32_t>(t)))
        debris.push_back(static_cast<std::int32_t>(t));
    }
    for (std::int32_t t : debris)
      debris_volume += SignedVolume(sb.x_rest, sb.tets[static_cast<std::size_t>(t)]);
    soft.RemoveTets(body, debris, state);
    result.removed_tets += static_cast<int>(debris.size());
    frontier = std::move(debris);
  }
  result.volume_mm3 = before - after + debris_volume;
  sb.removed_volume_mm3 += result.volume_mm3;
  if (cauterize) {
    if (sb.cauterized.size() < static_cast<std::size_t>(sb.x.cols())) {
      sb.cauterized.resize(static_cast<std::size_t>(sb.x.cols()), 0);
    }
    for (std::int32_t n : touched) sb.cauterized[static_cast<std::size_t>(n)] = 1;
  }
  return result;
}

void ShaverShave(const Model& model, int slot, const StepContext& context, State* state,
                 InstrumentScratch* scratch) {
  ShaveWith(model, slot, collision::ToolPart::kShaverTip, model.operations.shaver, false, "shave",
            context, state, scratch);
}

void CauteryShave(const Model& model, int slot, const StepContext& context, State* state,
                  InstrumentScratch* scratch) {
  ShaveWith(model, slot, collision::ToolPart::kCauteryTip, model.operations.electrocautery, true,
            "cauterize", context, state, scratch);
}

}  // namespace arthrosim::instruments
