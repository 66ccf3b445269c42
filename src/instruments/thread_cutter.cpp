// Cutter: the suture between the closing blades is cut (Choi et al. 2020, section III.1, Fig. 2b).
#include <algorithm>
#include <string>

#include "arthrosim/collision/proximity.h"
#include "arthrosim/instruments/cutting.h"
#include "arthrosim/physics/constraints.h"

namespace arthrosim::instruments {
namespace {

// Node `node` of thread `thread` is held to the bone: a fixed node of the Model (an anchor in
// bone) or an end of a runtime constraint whose other end is a bone.
bool BoneConnected(const Model& model, const State& state, int thread, std::int32_t node) {
  const ThreadModel& tm = model.threads[static_cast<std::size_t>(thread)];
  if (std::binary_search(tm.fixed_nodes.begin(), tm.fixed_nodes.end(), node)) return true;
  for (const SpringConstraint& c : state.constraints) {
    for (int side = 0; side < 2; ++side) {
      const ConstraintEnd& e = side == 0 ? c.a : c.b;
      const ConstraintEnd& other = side == 0 ? c.b : c.a;
      if (e.kind != ConstraintEnd::Kind::kThread || e.index != thread) continue;
      if (other.kind != ConstraintEnd::Kind::kBone) continue;
      for (int k = 0; k < 4; ++k) {
        if (e.nodes[static_cast<std::size_t>(k)] == node &&
            e.weights[static_cast<std::size_t>(k)] != 0)
          return true;
      }
    }
  }
  return false;
}

bool AnyBoneConnected(const Model& model, const State& state, int thread, std::int32_t first,
                      std::int32_t last) {
  for (std::int32_t n = first; n <= last; ++n) {
    if (BoneConnected(model, state, thread, n)) return true;
  }
  return false;
}

struct Nearest {
  int thread = -1;
  std::int32_t segment = -1;
  double dist2 = 0;
  Vec3 point = Vec3::Zero();
};

// The alive segment nearest to the blade triangle among those next to a node this slot touches.
Nearest NearestSegment(const StepContext& context, int slot, const State& state,
                       const std::array<Vec3, 3>& tri) {
  Nearest best;
  if (context.contacts == nullptr) return best;
  for (const physics::PointContact& c : context.contacts->contacts) {
    if (c.tool_slot != slot || c.target != physics::PointContact::Target::kThread) continue;
    const ThreadState& ts = state.threads[static_cast<std::size_t>(c.index)];
    const auto n = static_cast<std::int32_t>(ts.x.cols());
    for (std::int32_t node : c.nodes) {
      if (node < 0) continue;
      for (std::int32_t k = std::max(node - 1, 0); k <= std::min(node, n - 2); ++k) {
        if (!ts.node_alive[static_cast<std::size_t>(k)] ||
            !ts.node_alive[static_cast<std::size_t>(k + 1)])
          continue;
        const collision::ClosestPair p =
            collision::SegmentTriangle(ts.x.col(k), ts.x.col(k + 1), tri[0], tri[1], tri[2]);
        // Ties go to the lower (thread, segment): contacts come sorted, so the result is fixed.
        const bool better =
            best.thread < 0 || p.dist2 < best.dist2 ||
            (p.dist2 == best.dist2 &&
             (c.index < best.thread || (c.index == best.thread && k < best.segment)));
        if (better) best = Nearest{c.index, k, p.dist2, p.pa};
      }
    }
  }
  return best;
}

}  // namespace

std::int32_t CuttingPoint(const Model& model, const State& state, int thread, std::int32_t segment,
                          int* toward_end) {
  const ThreadState& ts = state.threads[static_cast<std::size_t>(thread)];
  // The strand (run of alive nodes) holding the segment.
  std::int32_t first = segment, last = segment + 1;
  while (first > 0 && ts.node_alive[static_cast<std::size_t>(first - 1)]) --first;
  while (last + 1 < ts.x.cols() && ts.node_alive[static_cast<std::size_t>(last + 1)]) ++last;
  const bool bone_before = AnyBoneConnected(model, state, thread, first, segment);
  const bool bone_after = AnyBoneConnected(model, state, thread, segment + 1, last);
  if (bone_before && bone_after) {
    *toward_end = 0;
    return segment + 1;
  }
  if (bone_after) {
    *toward_end = -1;
    return segment;
  }
  *toward_end = +1;
  return segment + 1;
}

void ThreadCutter(const Model& model, int slot, const StepContext& context, State* state,
                  InstrumentScratch* /*scratch*/) {
  const ToolState& tool = state->tools[static_cast<std::size_t>(slot)];
  if (context.prev_tools == nullptr) return;
  const CutterOptions& opt = model.operations.cutter;
  const ToolState& prev = (*context.prev_tools)[static_cast<std::size_t>(slot)];
  if (!JawClosing(tool, prev, 0.0) || !(prev.jaw < opt.cut_at_jaw && tool.jaw >= opt.cut_at_jaw)) {
    return;
  }
  std::array<Vec3, 3> tri;
  if (!BladeTriangle(model, tool, &tri)) return;
  // Table 1: the cutter cuts thread only.
  const Nearest near = NearestSegment(context, slot, *state, tri);
  if (near.thread < 0 || near.dist2 > opt.reach_mm * opt.reach_mm) return;
  int toward = 0;
  const std::int32_t cut = CuttingPoint(model, *state, near.thread, near.segment, &toward);
  ThreadState& ts = state->threads[static_cast<std::size_t>(near.thread)];
  std::int32_t removed = 0;
  auto kill = [&](std::int32_t n) {
    if (!ts.node_alive[static_cast<std::size_t>(n)]) return false;
    ts.node_alive[static_cast<std::size_t>(n)] = 0;
    ts.v.col(n).setZero();
    ++removed;
    return true;
  };
  if (toward == 0) {
    kill(cut);
  } else {
    // From the Cutting_Point to the free end of its strand.
    for (std::int32_t n = cut; n >= 0 && n < ts.x.cols(); n += toward) {
      if (!kill(n)) break;
    }
  }
  const int constraints = physics::RemoveConstraintsOnDeadThreadNodes(state);
  RecordEvent(model, slot, "thread_cut", model.threads[static_cast<std::size_t>(near.thread)].name,
              "segment=" + std::to_string(near.segment) + " cutting_point=" + std::to_string(cut) +
                  " removed_nodes=" + std::to_string(removed) +
                  " removed_constraints=" + std::to_string(constraints),
              near.point, state);
}

}  // namespace arthrosim::instruments
