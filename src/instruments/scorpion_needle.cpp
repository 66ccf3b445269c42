// Scorpion needle: Choi et al. 2020 section III.5 and Fig. 8. Button 1 grasps the tissue between
// the jaws and ties the nearest thread node to the tool; button 2, with both held and the tool on
// the tissue, passes the thread through along the penetration path (the centres of the surface
// triangles nearest the two jaw tips) and stitches the nodes inside to the tissue.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

#include "arthrosim/collision/instrument_shape.h"
#include "arthrosim/core/soft_nodes.h"
#include "arthrosim/physics/constraints.h"
#include "bone_contact.h"
#include "suture_ops.h"

namespace arthrosim::instruments {
namespace {

constexpr const char* kTissueTag = "scorpion_tissue";
constexpr const char* kThreadTag = "scorpion_thread";
constexpr const char* kStitchTag = "stitch";

std::string BodyName(const Model& model, const ConstraintEnd& end) {
  if (end.kind == ConstraintEnd::Kind::kThread)
    return model.threads[static_cast<std::size_t>(end.index)].name;
  if (end.kind == ConstraintEnd::Kind::kSoftBody)
    return model.soft_bodies[static_cast<std::size_t>(end.index)].name;
  return "";
}

void Release(const Model& model, int slot, std::int64_t id, const char* reason, State* state) {
  const SpringConstraint* c = physics::FindConstraint(*state, id);
  const std::string body = BodyName(model, c->b);
  const Vec3 at = physics::EndPosition(*state, c->b);
  char detail[128];
  std::snprintf(detail, sizeof detail, "constraint=%lld reason=%s", static_cast<long long>(id),
                reason);
  physics::RemoveConstraint(state, id);
  RecordEvent(model, slot, "release", body, detail, at, state);
}

// World positions of the two jaw tips at the current jaw value: side 0 (upper jaw, the paper's
// "jaw point") and side 1 (lower jaw, the "end of the tool" where the needle starts).
void JawTips(const Model& model, const ToolState& tool, Vec3* upper, Vec3* lower) {
  const InstrumentModel& m = model.instruments[static_cast<std::size_t>(tool.instrument)];
  for (const collision::ToolPrimitive& p : collision::InstrumentPrimitivesLocal(m, tool.jaw)) {
    if (p.part != collision::ToolPart::kJaw) continue;
    (p.side == 0 ? *upper : *lower) = tool.pose.Apply(p.core.v[2]);
  }
}

// Button 1, tissue: grasp what lies between the jaws once they are closed to grasp_jaw (not
// while they are slid open around the tissue); release beyond Dist_limit_2 or when button 1 is
// let go.
void HoldTissue(const Model& model, int slot, const StepContext& context, State* state) {
  const ScorpionNeedleOptions& opt = model.operations.scorpion_needle;
  const ToolState& tool = state->tools[static_cast<std::size_t>(slot)];
  const std::int64_t held = ToolConstraint(*state, slot, kTissueTag);
  if (held >= 0) {
    if (!Button1(tool)) return Release(model, slot, held, "button_1_up", state);
    if (ConstraintStretchMm(*state, held) > opt.dist_limit_2_mm)
      return Release(model, slot, held, "distance", state);
    return;
  }
  if (!Button1(tool) || tool.jaw < opt.grasp_jaw || context.world == nullptr) return;
  Vec3 upper = Vec3::Zero(), lower = Vec3::Zero();
  JawTips(model, tool, &upper, &lower);
  SurfacePoint best;
  best.distance_mm = std::numeric_limits<double>::infinity();
  for (const std::int32_t body : TouchedSoftBodies(context, slot)) {
    const SurfacePoint p =
        NearestSurfacePoint(*state, *context.world, body, lower, upper, opt.dist_limit_2_mm);
    if (p.body >= 0 && p.distance_mm < best.distance_mm) best = p;
  }
  if (best.body < 0) return;
  ConstraintEnd end;
  end.kind = ConstraintEnd::Kind::kSoftBody;
  end.index = best.body;
  for (std::size_t k = 0; k < 3; ++k) {
    end.nodes[k] = best.nodes[k];
    end.weights[k] = best.weights[k];
  }
  const std::int64_t id =
      AddToolSpring(state, slot, best.point_mm, end, opt.tissue_stiffness_n_per_mm, kTissueTag);
  char detail[96];
  std::snprintf(detail, sizeof detail, "constraint=%lld tri=%d", static_cast<long long>(id),
                best.tri);
  RecordEvent(model, slot, "grasp", model.soft_bodies[static_cast<std::size_t>(best.body)].name,
              detail, best.point_mm, state);
}

// Button 1, thread: the live, not fixed thread node nearest the tool's end point within
// Dist_limit_1 is tied to the tool. Only while no tissue is held (the paper's order: load the
// suture, then take the tissue), so the thread just passed is not caught again.
void HoldThread(const Model& model, int slot, State* state) {
  const ScorpionNeedleOptions& opt = model.operations.scorpion_needle;
  const ToolState& tool = state->tools[static_cast<std::size_t>(slot)];
  const std::int64_t held = ToolConstraint(*state, slot, kThreadTag);
  if (held >= 0) {
    if (!Button1(tool)) Release(model, slot, held, "button_1_up", state);
    return;
  }
  if (!Button1(tool) || ToolConstraint(*state, slot, kTissueTag) >= 0) return;
  const Vec3 tip = tool.pose.position_mm;
  const CaughtNode c = CatchNearestThreadNode(model, slot, tip, opt.dist_limit_1_mm, {},
                                              opt.thread_stiffness_n_per_mm, kThreadTag, state);
  if (c.thread < 0) return;
  char detail[96];
  std::snprintf(detail, sizeof detail, "constraint=%lld node=%d distance_mm=%.3f",
                static_cast<long long>(c.constraint), c.node, c.distance_mm);
  RecordEvent(model, slot, "thread_catch", model.threads[static_cast<std::size_t>(c.thread)].name,
              detail, state->threads[static_cast<std::size_t>(c.thread)].x.col(c.node), state);
}

// Barycentric coordinates of p in the live tet of `body` that contains it (or, if none does
// within rounding, the live tet where p is least outside): tet nodes and weights.
void TetAt(const State& state, int body, const Vec3& p, std::array<std::int32_t, 4>* nodes,
           std::array<double, 4>* weights) {
  const SoftBodyState& sb = state.soft_bodies[static_cast<std::size_t>(body)];
  double best = -std::numeric_limits<double>::infinity();
  for (std::size_t t = 0; t < sb.tets.size(); ++t) {
    if (!sb.tet_alive.empty() && !sb.tet_alive[t]) continue;
    const mesh::Tet& tet = sb.tets[t];
    const Vec3 a = sb.x.col(tet[0]);
    Mat3 e;
    e << sb.x.col(tet[1]) - a, sb.x.col(tet[2]) - a, sb.x.col(tet[3]) - a;
    const double det = e.determinant();
    if (!(std::abs(det) > 0)) continue;
    const Vec3 w = e.inverse() * (p - a);
    const std::array<double, 4> bary{1 - w.sum(), w.x(), w.y(), w.z()};
    const double worst = std::min(std::min(bary[0], bary[1]), std::min(bary[2], bary[3]));
    if (worst > best) {
      best = worst;
      *weights = bary;
      *nodes = {tet[0], tet[1], tet[2], tet[3]};
    }
    if (best >= 0) break;  // inside: the first containing tet in index order
  }
}

// Distance (mm) from p to the nearest node of the region `tendon_edge` on `body` that still
// belongs to the tissue (NodesInAliveTets: debridement leaves debris nodes where they were cut,
// which a reduced tendon leaves behind), or -1 if the scenario has no such region on that body
// or none of its nodes is left.
double DistanceToTendonEdge(const Model& model, const State& state, int body, const Vec3& p) {
  const int r = model.FindRegion("tendon_edge");
  if (r < 0) return -1;
  const Region& region = model.regions[static_cast<std::size_t>(r)];
  if (region.body != model.soft_bodies[static_cast<std::size_t>(body)].name) return -1;
  double best = -1;
  const SoftBodyState& tissue = state.soft_bodies[static_cast<std::size_t>(body)];
  const std::vector<std::uint8_t> in_tissue = NodesInAliveTets(tissue);
  const Points& x = tissue.x;
  for (const std::int32_t n : region.nodes) {
    if (!in_tissue[static_cast<std::size_t>(n)]) continue;
    const double d = (x.col(n) - p).norm();
    if (best < 0 || d < best) best = d;
  }
  return best;
}

// True if segment (a, b) comes within clearance_mm of any bone surface.
bool SegmentNearBone(const State& state, const Vec3& a, const Vec3& b, double clearance_mm) {
  for (const BoneState& bone : state.bones)
    if (TouchBone(bone.surface, a, b, clearance_mm).triangles > 0) return true;
  return false;
}

// Button 2: the paper's penetration path and thread placement, then the stitch springs. The
// paper lays the free end straight on along the path; where that line would run into bone (a
// tail under the acromion), the rest of the tail is laid back along the needle's shaft, the way
// the needle drew it out, instead of through the bone.
void PassThread(const Model& model, int slot, const StepContext& context, State* state) {
  const ScorpionNeedleOptions& opt = model.operations.scorpion_needle;
  const std::int64_t thread_id = ToolConstraint(*state, slot, kThreadTag);
  const std::int64_t tissue_id = ToolConstraint(*state, slot, kTissueTag);
  if (thread_id < 0 || tissue_id < 0 || context.world == nullptr) return;
  const SpringConstraint thread_c = *physics::FindConstraint(*state, thread_id);
  const int body = physics::FindConstraint(*state, tissue_id)->b.index;
  const std::vector<std::int32_t> touched = TouchedSoftBodies(context, slot);
  if (!std::binary_search(touched.begin(), touched.end(), body)) return;
  const ToolState& tool = state->tools[static_cast<std::size_t>(slot)];
  Vec3 upper = Vec3::Zero(), lower = Vec3::Zero();
  JawTips(model, tool, &upper, &lower);
  const double reach = (upper - lower).norm() + opt.dist_limit_2_mm;
  const SurfacePoint in = NearestSurfacePoint(*state, *context.world, body, lower, lower, reach);
  const SurfacePoint out = NearestSurfacePoint(*state, *context.world, body, upper, upper, reach);
  if (in.tri < 0 || out.tri < 0 || in.tri == out.tri) return;  // no path through the tissue
  const Points& x = state->soft_bodies[static_cast<std::size_t>(body)].x;
  const auto centre = [&](const SurfacePoint& s) {
    return (x.col(s.nodes[0]) + x.col(s.nodes[1]) + x.col(s.nodes[2])) / 3.0;
  };
  const Vec3 entry = centre(in), exit = centre(out);
  const Vec3 dir = (exit - entry).normalized();  // away from the tissue, through the exit
  // The held node goes to the entry point; the node `through` further toward the free end to
  // the exit point (at least nodes_through, more if the path is longer than that many rest
  // segments, so the thread is not stretched through the tissue); nodes between on the path;
  // the rest at node_spacing along dir.
  const int thread = thread_c.b.index;
  const int held = thread_c.b.nodes[0];
  ThreadState& th = state->threads[static_cast<std::size_t>(thread)];
  const int count = static_cast<int>(th.x.cols());
  const double rest = (model.threads[static_cast<std::size_t>(thread)].initial.nodes.col(1) -
                       model.threads[static_cast<std::size_t>(thread)].initial.nodes.col(0))
                          .norm();
  const int through =
      std::max(opt.nodes_through, static_cast<int>(std::ceil((exit - entry).norm() / rest - 1e-9)));
  const int step = held + through < count ? 1 : -1;
  if (held + step * through < 0 || held + step * through >= count) return;  // too short
  physics::RemoveConstraint(state, thread_id);
  const double clearance_mm = 0.5 * model.threads[static_cast<std::size_t>(thread)].diameter_mm +
                              model.contact.contact_distance_mm;
  const Vec3 back_to_portal = -(tool.pose.orientation * Vec3::UnitZ());
  bool turned = false;  // the tail turns once, where the needle drew it out
  for (int j = 0; held + step * j >= 0 && held + step * j < count; ++j) {
    const int n = held + step * j;
    if (j <= through) {
      th.x.col(n) = entry + (exit - entry) * (static_cast<double>(j) / through);
    } else {
      const Vec3 prev = th.x.col(n - step);
      turned =
          turned || SegmentNearBone(*state, prev, prev + opt.node_spacing_mm * dir, clearance_mm);
      th.x.col(n) = prev + opt.node_spacing_mm * (turned ? back_to_portal : dir);
    }
    th.v.col(n).setZero();
  }
  // The limb behind the held node follows it to the entry (each node drawn to within a rest
  // segment of the next, toward the anchor or fixed end), so the pass stretches no segment.
  for (int n = held - step; n >= 0 && n < count; n -= step) {
    if (std::binary_search(model.threads[static_cast<std::size_t>(thread)].fixed_nodes.begin(),
                           model.threads[static_cast<std::size_t>(thread)].fixed_nodes.end(), n))
      break;
    const Vec3 next = th.x.col(n + step);
    const Vec3 d = th.x.col(n) - next;
    if (d.norm() <= rest) break;
    th.x.col(n) = next + d * (rest / d.norm());
    th.v.col(n).setZero();
  }
  for (int j = 0; j <= through; ++j) {
    SpringConstraint c;
    c.tag = kStitchTag;
    c.a.kind = ConstraintEnd::Kind::kThread;
    c.a.index = thread;
    c.a.nodes[0] = held + step * j;
    c.a.weights[0] = 1;
    c.b.kind = ConstraintEnd::Kind::kSoftBody;
    c.b.index = body;
    TetAt(*state, body, th.x.col(held + step * j), &c.b.nodes, &c.b.weights);
    c.stiffness_n_per_mm = opt.stitch_stiffness_n_per_mm;
    c.slide_friction_n = opt.stitch_friction_n;
    physics::AddConstraint(state, std::move(c));
  }
  const double edge_mm = DistanceToTendonEdge(model, *state, body, entry);
  char detail[320];
  std::snprintf(
      detail, sizeof detail,
      "thread=%s entry_node=%d exit_node=%d entry_mm=%s exit_mm=%s stitches=%d%s",
      model.threads[static_cast<std::size_t>(thread)].name.c_str(), held, held + step * through,
      FormatPoint(entry).c_str(), FormatPoint(exit).c_str(), through + 1,
      edge_mm >= 0
          ? (" bite_to_edge_mm=" + std::to_string(edge_mm) + " bite_mm=" + std::to_string(edge_mm))
                .c_str()
          : "");
  RecordEvent(model, slot, "suture_pass", model.soft_bodies[static_cast<std::size_t>(body)].name,
              detail, entry, state);
}

}  // namespace

void ScorpionNeedleOperation(const Model& model, int slot, const StepContext& context, State* state,
                             InstrumentScratch* /*scratch*/) {
  HoldThread(model, slot, state);
  HoldTissue(model, slot, context, state);
  // One pass per press of button 2 (it goes down this step): a press held over several steps
  // must not load the limb's free end again and pass it a second time once the tissue slips.
  const bool was_down = context.prev_tools != nullptr &&
                        Button2((*context.prev_tools)[static_cast<std::size_t>(slot)]);
  if (Button2(state->tools[static_cast<std::size_t>(slot)]) && !was_down)
    PassThread(model, slot, context, state);
}

}  // namespace arthrosim::instruments
