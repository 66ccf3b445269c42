#include "arthrosim/physics/constraints.h"

#include <algorithm>
#include <cmath>
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

ConstraintEnd ThreadPointEnd(std::int32_t thread, double s) {
  if (thread < 0 || !(s >= 0))
    throw std::invalid_argument("thread point end needs a thread index >= 0 and s >= 0");
  ConstraintEnd e;
  e.kind = ConstraintEnd::Kind::kThread;
  e.index = thread;
  const double i = std::floor(s);
  e.nodes[0] = static_cast<std::int32_t>(i);
  e.weights[0] = 1.0 - (s - i);
  if (s > i) {
    e.nodes[1] = e.nodes[0] + 1;
    e.weights[1] = s - i;
  }
  return e;
}

double ThreadEndParameter(const ConstraintEnd& end) {
  const bool single = end.weights[1] == 0 && end.weights[2] == 0 && end.weights[3] == 0;
  const bool pair = end.nodes[1] == end.nodes[0] + 1 && end.weights[2] == 0 &&
                    end.weights[3] == 0 && std::abs(end.weights[0] + end.weights[1] - 1) < 1e-9;
  if (end.kind != ConstraintEnd::Kind::kThread || end.nodes[0] < 0 || !(single || pair))
    throw std::invalid_argument("constraint end is not a point along a thread");
  return end.nodes[0] + (single ? 0.0 : end.weights[1]);
}

const ConstraintEnd* SlidingEnd(const SpringConstraint& c) {
  if (!(c.slide_friction_n >= 0)) return nullptr;
  if (c.a.kind == ConstraintEnd::Kind::kThread) return &c.a;
  if (c.b.kind == ConstraintEnd::Kind::kThread) return &c.b;
  return nullptr;
}

namespace {

bool Alive(const ThreadState& t, int n) {
  return n >= 0 && n < t.x.cols() &&
         (t.node_alive.empty() || t.node_alive[static_cast<std::size_t>(n)] != 0);
}

// Moves arc parameter s by `distance_mm` along the chain (dir +1 toward higher node indices,
// -1 lower), segment by segment over live segments; stops at a dead node or a chain end.
double WalkAlong(const ThreadState& t, double s, int dir, double distance_mm) {
  const int last = static_cast<int>(t.x.cols()) - 1;
  while (distance_mm > 0) {
    const double fl = std::floor(s);
    const int seg =
        dir > 0 ? static_cast<int>(fl) : (s > fl ? static_cast<int>(fl) : static_cast<int>(fl) - 1);
    if (seg < 0 || seg + 1 > last || !Alive(t, seg) || !Alive(t, seg + 1)) break;
    const double len = (t.x.col(seg + 1) - t.x.col(seg)).norm();
    if (!(len > 0)) break;
    const double room_mm = (dir > 0 ? seg + 1 - s : s - seg) * len;
    if (distance_mm < room_mm) {
      s += dir * distance_mm / len;
      break;
    }
    s = dir > 0 ? seg + 1 : seg;
    distance_mm -= room_mm;
  }
  return std::clamp(s, 0.0, static_cast<double>(last));
}

// New arc parameter of a sliding end `e` under its constraint's spring, or s if it holds.
double SlidTo(const State& state, const SpringConstraint& c, const ConstraintEnd& e, double s) {
  const ThreadState& t = state.threads[static_cast<std::size_t>(e.index)];
  const int last = static_cast<int>(t.x.cols()) - 1;
  if (last < 1 || !(c.stiffness_n_per_mm > 0)) return s;
  const ConstraintEnd& other = &e == &c.a ? c.b : c.a;
  const Vec3 d = EndPosition(state, other) - EndPosition(state, e);
  const double len = d.norm();
  if (!(len > c.rest_length_mm)) return s;
  const Vec3 force_n = c.stiffness_n_per_mm * (len - c.rest_length_mm) / len * d;
  const int seg = std::min(static_cast<int>(std::floor(s)), last - 1);
  const Vec3 tangent = t.x.col(seg + 1) - t.x.col(seg);
  if (!(tangent.norm() > 0)) return s;
  const double along_n = force_n.dot(tangent.normalized());
  const double excess_n = std::abs(along_n) - c.slide_friction_n;
  if (!(excess_n > 0)) return s;
  return WalkAlong(t, s, along_n > 0 ? 1 : -1, excess_n / c.stiffness_n_per_mm);
}

}  // namespace

int SlideConstraintEnds(State* state) {
  int moved = 0;
  for (SpringConstraint& c : state->constraints) {
    const ConstraintEnd* sliding = SlidingEnd(c);
    if (sliding == nullptr) continue;
    CheckIndex(state->threads, sliding->index, "thread");
    const double s = ThreadEndParameter(*sliding);
    const double to = SlidTo(*state, c, *sliding, s);
    if (to == s) continue;
    ConstraintEnd& end = sliding == &c.a ? c.a : c.b;
    end = ThreadPointEnd(end.index, to);
    ++moved;
  }
  return moved;
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
