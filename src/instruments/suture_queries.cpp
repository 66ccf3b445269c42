// Geometric queries and tool-held springs shared by the grasping and suturing operations.
#include <cstdio>

#include "arthrosim/collision/proximity.h"
#include "arthrosim/physics/constraints.h"
#include "suture_ops.h"

#include <algorithm>

namespace arthrosim::instruments {

SurfacePoint NearestSurfacePoint(const State& state, const collision::CollisionWorld& world,
                                 int body, const Vec3& a, const Vec3& b, double reach) {
  SurfacePoint best;
  if (body < 0 || body >= static_cast<int>(world.soft.size())) return best;
  const collision::CollisionWorld::SoftEntry& entry = world.soft[static_cast<std::size_t>(body)];
  if (!entry.built || entry.bvh.empty()) return best;
  collision::Box query;
  query.Add(a);
  query.Add(b);
  std::vector<std::int32_t> candidates;
  entry.bvh.Query(query.Inflated(reach + kTreeSlackMm), &candidates);
  const Points& x = state.soft_bodies[static_cast<std::size_t>(body)].x;
  double best_d2 = reach * reach;
  for (const std::int32_t t : candidates) {  // ascending, so ties keep the lower index
    const mesh::Tri& tri = entry.surface.tris[static_cast<std::size_t>(t)];
    const collision::ClosestPair c =
        collision::SegmentTriangle(a, b, x.col(tri[0]), x.col(tri[1]), x.col(tri[2]));
    if (c.dist2 > best_d2 || (best.tri >= 0 && c.dist2 == best_d2)) continue;
    best_d2 = c.dist2;
    best.body = body;
    best.tri = t;
    best.nodes = {tri[0], tri[1], tri[2]};
    best.weights = c.wb;
    best.point_mm = c.pb;
    best.distance_mm = std::sqrt(c.dist2);
  }
  return best;
}

std::vector<std::int32_t> TouchedSoftBodies(const StepContext& context, int slot) {
  std::vector<std::int32_t> bodies;
  if (context.contacts == nullptr) return bodies;
  for (const physics::PointContact& c : context.contacts->contacts) {
    if (c.tool_slot != slot || c.target != physics::PointContact::Target::kSoftBody) continue;
    if (!(c.force_n > 0)) continue;
    if (std::find(bodies.begin(), bodies.end(), c.index) == bodies.end()) bodies.push_back(c.index);
  }
  std::sort(bodies.begin(), bodies.end());
  return bodies;
}

std::int64_t ToolConstraint(const State& state, int slot, const char* tag) {
  for (const SpringConstraint& c : state.constraints)
    if (c.tag == tag && c.a.kind == ConstraintEnd::Kind::kTool && c.a.index == slot) return c.id;
  return -1;
}

std::int64_t AddToolSpring(State* state, int slot, const Vec3& world_point_mm,
                           const ConstraintEnd& other, double stiffness_n_per_mm, const char* tag) {
  const Pose& pose = state->tools[static_cast<std::size_t>(slot)].pose;
  SpringConstraint c;
  c.tag = tag;
  c.a.kind = ConstraintEnd::Kind::kTool;
  c.a.index = slot;
  c.a.offset_mm = pose.orientation.conjugate() * (world_point_mm - pose.position_mm);
  c.b = other;
  c.stiffness_n_per_mm = stiffness_n_per_mm;
  c.rest_length_mm = 0;
  return physics::AddConstraint(state, std::move(c));
}

CaughtNode CatchNearestThreadNode(const Model& model, int slot, const Vec3& point_mm,
                                  double reach_mm, const std::vector<bool>& skip_thread,
                                  double stiffness_n_per_mm, const char* tag, State* state) {
  CaughtNode best;
  best.distance_mm = reach_mm;
  for (std::size_t t = 0; t < state->threads.size(); ++t) {
    if (t < skip_thread.size() && skip_thread[t]) continue;
    const ThreadState& th = state->threads[t];
    const std::vector<std::int32_t>& fixed = model.threads[t].fixed_nodes;
    for (int n = 0; n < th.x.cols(); ++n) {
      if (!th.node_alive.empty() && !th.node_alive[static_cast<std::size_t>(n)]) continue;
      if (std::binary_search(fixed.begin(), fixed.end(), n)) continue;
      const double d = (th.x.col(n) - point_mm).norm();
      if (d < best.distance_mm) {
        best.distance_mm = d;
        best.thread = static_cast<int>(t);
        best.node = n;
      }
    }
  }
  if (best.thread < 0) return best;
  ConstraintEnd end;
  end.kind = ConstraintEnd::Kind::kThread;
  end.index = best.thread;
  end.nodes[0] = best.node;
  end.weights[0] = 1;
  const Vec3 p = state->threads[static_cast<std::size_t>(best.thread)].x.col(best.node);
  best.constraint = AddToolSpring(state, slot, p, end, stiffness_n_per_mm, tag);
  return best;
}

double ConstraintStretchMm(const State& state, std::int64_t id) {
  const SpringConstraint* c = physics::FindConstraint(state, id);
  if (c == nullptr) return 0;
  return (physics::EndPosition(state, c->a) - physics::EndPosition(state, c->b)).norm();
}

void JawSegment(const Model& model, const ToolState& tool, Vec3* hinge, Vec3* tip) {
  const InstrumentModel& m = model.instruments[static_cast<std::size_t>(tool.instrument)];
  *hinge = tool.pose.Apply(Vec3(0, 0, -std::max(m.tip_length_mm, 1e-3)));
  *tip = tool.pose.Apply(Vec3::Zero());
}

std::string FormatPoint(const Vec3& p) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "%.3f,%.3f,%.3f", p.x(), p.y(), p.z());
  return buf;
}

}  // namespace arthrosim::instruments
