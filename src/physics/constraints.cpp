#include "arthrosim/physics/constraints.h"

#include <algorithm>
#include <stdexcept>

namespace arthrosim::physics {

namespace {

bool EndUsesNode(const ConstraintEnd& e, std::int32_t node) {
  for (int k = 0; k < 4; ++k)
    if (e.nodes[k] == node && e.weights[k] != 0) return true;
  return false;
}

Vec3 WeightedNodes(const Points& x, const ConstraintEnd& e) {
  Vec3 p = Vec3::Zero();
  for (int k = 0; k < 4; ++k) {
    if (e.nodes[k] < 0 || e.weights[k] == 0) continue;
    if (e.nodes[k] >= x.cols())
      throw std::invalid_argument("constraint end node " + std::to_string(e.nodes[k]) +
                                  " out of range");
    p += e.weights[k] * x.col(e.nodes[k]);
  }
  return p;
}

template <class Vec>
void CheckIndex(const Vec& v, std::int32_t index, const char* what) {
  if (index < 0 || index >= static_cast<std::int32_t>(v.size()))
    throw std::invalid_argument(std::string("constraint end ") + what + " index " +
                                std::to_string(index) + " out of range");
}

}  // namespace

std::int64_t AddConstraint(State* state, SpringConstraint c) {
  if (!(c.stiffness_n_per_mm >= 0) || !(c.rest_length_mm >= 0))
    throw std::invalid_argument("spring constraint needs stiffness >= 0 and rest length >= 0");
  c.id = state->next_constraint_id++;
  // Ids increase, so appending keeps the vector sorted; insert in place in case a restored
  // state carries a larger id than next_constraint_id.
  auto it = std::upper_bound(state->constraints.begin(), state->constraints.end(), c.id,
                             [](std::int64_t id, const SpringConstraint& s) { return id < s.id; });
  state->constraints.insert(it, std::move(c));
  return state->next_constraint_id - 1;
}

bool RemoveConstraint(State* state, std::int64_t id) {
  auto it = std::lower_bound(state->constraints.begin(), state->constraints.end(), id,
                             [](const SpringConstraint& s, std::int64_t v) { return s.id < v; });
  if (it == state->constraints.end() || it->id != id) return false;
  state->constraints.erase(it);
  return true;
}

const SpringConstraint* FindConstraint(const State& state, std::int64_t id) {
  auto it = std::lower_bound(state.constraints.begin(), state.constraints.end(), id,
                             [](const SpringConstraint& s, std::int64_t v) { return s.id < v; });
  return it != state.constraints.end() && it->id == id ? &*it : nullptr;
}

std::vector<std::int64_t> FindConstraintsByTag(const State& state, const std::string& tag) {
  std::vector<std::int64_t> ids;
  for (const SpringConstraint& c : state.constraints)
    if (c.tag == tag) ids.push_back(c.id);
  return ids;
}

std::vector<std::int64_t> FindConstraintsByEnd(const State& state, ConstraintEnd::Kind kind,
                                               std::int32_t index, std::int32_t node) {
  std::vector<std::int64_t> ids;
  for (const SpringConstraint& c : state.constraints) {
    for (const ConstraintEnd* e : {&c.a, &c.b}) {
      if (e->kind == kind && e->index == index && (node < 0 || EndUsesNode(*e, node))) {
        ids.push_back(c.id);
        break;
      }
    }
  }
  return ids;
}

Vec3 EndPosition(const State& state, const ConstraintEnd& end) {
  switch (end.kind) {
    case ConstraintEnd::Kind::kWorld:
    case ConstraintEnd::Kind::kBone:  // bones are fixed: the point is stored in world
      return end.offset_mm;
    case ConstraintEnd::Kind::kTool:
      CheckIndex(state.tools, end.index, "tool");
      return state.tools[end.index].pose.Apply(end.offset_mm);
    case ConstraintEnd::Kind::kSoftBody:
      CheckIndex(state.soft_bodies, end.index, "soft body");
      return WeightedNodes(state.soft_bodies[end.index].x, end);
    case ConstraintEnd::Kind::kThread:
      CheckIndex(state.threads, end.index, "thread");
      return WeightedNodes(state.threads[end.index].x, end);
  }
  return end.offset_mm;
}

SpringSet BuildPointSprings(const State& state) {
  SpringSet out;
  BuildPointSprings(state, &out);
  return out;
}

void BuildPointSprings(const State& state, SpringSet* springs) {
  SpringSet& out = *springs;
  out.clear();
  for (const SpringConstraint& c : state.constraints) {
    const ConstraintEnd* ends[2] = {&c.a, &c.b};
    for (int side = 0; side < 2; ++side) {
      const ConstraintEnd& self = *ends[side];
      const ConstraintEnd& other = *ends[1 - side];
      PointSpring ps;
      if (self.kind == ConstraintEnd::Kind::kThread) {
        ps.target = PointContact::Target::kThread;
      } else if (self.kind == ConstraintEnd::Kind::kSoftBody) {
        ps.target = PointContact::Target::kSoftBody;
      } else {
        continue;
      }
      ps.index = self.index;
      ps.nodes = self.nodes;
      ps.weights = self.weights;
      ps.anchor_mm = EndPosition(state, other);
      ps.stiffness_n_per_mm = c.stiffness_n_per_mm;
      ps.rest_length_mm = c.rest_length_mm;
      ps.constraint_id = c.id;
      out.push_back(ps);
    }
  }
}

int RemoveConstraintsOnDeadThreadNodes(State* state) {
  const auto dead = [&](const ConstraintEnd& e) {
    if (e.kind != ConstraintEnd::Kind::kThread) return false;
    if (e.index < 0 || e.index >= static_cast<std::int32_t>(state->threads.size())) return false;
    const ThreadState& t = state->threads[e.index];
    for (int k = 0; k < 4; ++k) {
      const std::int32_t n = e.nodes[k];
      if (n >= 0 && e.weights[k] != 0 && n < static_cast<std::int32_t>(t.node_alive.size()) &&
          !t.node_alive[n])
        return true;
    }
    return false;
  };
  const std::size_t before = state->constraints.size();
  state->constraints.erase(
      std::remove_if(state->constraints.begin(), state->constraints.end(),
                     [&](const SpringConstraint& c) { return dead(c.a) || dead(c.b); }),
      state->constraints.end());
  return static_cast<int>(before - state->constraints.size());
}

}  // namespace arthrosim::physics
