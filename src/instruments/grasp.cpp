// Grasper (tissue) and retriever (thread): Choi et al. 2020 section III.4 and Fig. 6. The
// spring's tool end is the grasped point's place in the tool frame at the moment of grasping, so
// the grasped point follows the tool rigidly (rest length 0) and Dist_Limit is the stretch at
// which the tissue or thread slips out of the jaw.
#include <cstdio>
#include <limits>

#include "arthrosim/physics/constraints.h"
#include "suture_ops.h"

namespace arthrosim::instruments {
namespace {

constexpr const char* kGraspTag = "grasp";

// Releases the slot's grasp if the jaw opened or the spring stretched beyond the limit; true if
// a grasp is (still) held afterwards.
bool KeepOrRelease(const Model& model, int slot, const GraspOptions& opt, State* state) {
  const std::int64_t id = ToolConstraint(*state, slot, kGraspTag);
  if (id < 0) return false;
  const ToolState& tool = state->tools[static_cast<std::size_t>(slot)];
  const bool open = tool.jaw < opt.jaw_closed;
  const double stretch_mm = ConstraintStretchMm(*state, id);
  if (!open && stretch_mm <= opt.dist_limit_mm) return true;
  const SpringConstraint* c = physics::FindConstraint(*state, id);
  const ConstraintEnd held = c->b;
  const Vec3 at = physics::EndPosition(*state, held);
  const std::string body = held.kind == ConstraintEnd::Kind::kThread
                               ? model.threads[static_cast<std::size_t>(held.index)].name
                               : model.soft_bodies[static_cast<std::size_t>(held.index)].name;
  physics::RemoveConstraint(state, id);
  char detail[160];
  std::snprintf(detail, sizeof detail, "constraint=%lld reason=%s stretch_mm=%.3f",
                static_cast<long long>(id), open ? "jaw_open" : "distance", stretch_mm);
  RecordEvent(model, slot, "release", body, detail, at, state);
  return false;
}

void GraspTissue(const Model& model, int slot, const StepContext& context, State* state) {
  const GraspOptions& opt = model.operations.grasper;
  if (KeepOrRelease(model, slot, opt, state)) return;
  const ToolState& tool = state->tools[static_cast<std::size_t>(slot)];
  if (tool.jaw < opt.jaw_closed || context.world == nullptr) return;
  Vec3 hinge, tip;
  JawSegment(model, tool, &hinge, &tip);
  SurfacePoint best;
  best.distance_mm = std::numeric_limits<double>::infinity();
  for (const std::int32_t body : TouchedSoftBodies(context, slot)) {
    const SurfacePoint p =
        NearestSurfacePoint(*state, *context.world, body, hinge, tip, opt.dist_limit_mm);
    if (p.body >= 0 && p.distance_mm < best.distance_mm) best = p;
  }
  if (best.body < 0) return;
  ConstraintEnd end;
  end.kind = ConstraintEnd::Kind::kSoftBody;
  end.index = best.body;
  for (int k = 0; k < 3; ++k) {
    end.nodes[static_cast<std::size_t>(k)] = best.nodes[static_cast<std::size_t>(k)];
    end.weights[static_cast<std::size_t>(k)] = best.weights[static_cast<std::size_t>(k)];
  }
  const std::int64_t id =
      AddToolSpring(state, slot, best.point_mm, end, opt.stiffness_n_per_mm, kGraspTag);
  char detail[160];
  std::snprintf(detail, sizeof detail, "constraint=%lld tri=%d gap_mm=%.3f",
                static_cast<long long>(id), best.tri, best.distance_mm);
  RecordEvent(model, slot, "grasp", model.soft_bodies[static_cast<std::size_t>(best.body)].name,
              detail, best.point_mm, state);
}

// Nearest live thread node to the segment (a, b) within reach: (thread, node), or thread -1.
std::pair<int, int> NearestThreadNode(const State& state, const Vec3& a, const Vec3& b,
                                      double reach) {
  std::pair<int, int> best{-1, -1};
  double best_d = reach;
  const Vec3 ab = b - a;
  const double len2 = ab.squaredNorm();
  for (std::size_t t = 0; t < state.threads.size(); ++t) {
    const ThreadState& th = state.threads[t];
    for (int n = 0; n < th.x.cols(); ++n) {
      if (!th.node_alive.empty() && !th.node_alive[static_cast<std::size_t>(n)]) continue;
      const Vec3 p = th.x.col(n);
      const double s = len2 > 0 ? std::clamp((p - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
      const double d = (p - (a + s * ab)).norm();
      if (d < best_d) {
        best_d = d;
        best = {static_cast<int>(t), n};
      }
    }
  }
  return best;
}

void GraspThread(const Model& model, int slot, State* state) {
  const GraspOptions& opt = model.operations.retriever;
  if (KeepOrRelease(model, slot, opt, state)) return;
  const ToolState& tool = state->tools[static_cast<std::size_t>(slot)];
  if (tool.jaw < opt.jaw_closed) return;
  Vec3 hinge, tip;
  JawSegment(model, tool, &hinge, &tip);
  const auto [thread, node] = NearestThreadNode(*state, hinge, tip, opt.dist_limit_mm);
  if (thread < 0) return;
  ConstraintEnd end;
  end.kind = ConstraintEnd::Kind::kThread;
  end.index = thread;
  end.nodes[0] = node;
  end.weights[0] = 1.0;
  const Vec3 p = state->threads[static_cast<std::size_t>(thread)].x.col(node);
  const std::int64_t id = AddToolSpring(state, slot, p, end, opt.stiffness_n_per_mm, kGraspTag);
  char detail[96];
  std::snprintf(detail, sizeof detail, "constraint=%lld node=%d", static_cast<long long>(id), node);
  RecordEvent(model, slot, "grasp", model.threads[static_cast<std::size_t>(thread)].name, detail, p,
              state);
}

}  // namespace

void GrasperOperation(const Model& model, int slot, const StepContext& context, State* state,
                      InstrumentScratch* /*scratch*/) {
  GraspTissue(model, slot, context, state);
}

void RetrieverOperation(const Model& model, int slot, const StepContext& /*context*/, State* state,
                        InstrumentScratch* /*scratch*/) {
  GraspThread(model, slot, state);
}

}  // namespace arthrosim::instruments
