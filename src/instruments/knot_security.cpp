// Knot queries and the knot security pull test (docs/operations.md "Knot tying"): no open
// simulator says whether a tied knot holds; this loads both limbs of a copy of the knot and
// measures how far it slips (clinically a knot that slips more than 3 mm has failed).
#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "arthrosim/instruments/knot_pusher.h"
#include "arthrosim/physics/constraints.h"
#include "arthrosim/physics/thread_chain.h"

namespace arthrosim::instruments {
namespace {

constexpr double kPullLeverMm = 1.0e4;  // pull springs reach this far: force constant to 1e-4

Vec3 Node(const State& state, int thread, int node) {
  return state.threads[static_cast<std::size_t>(thread)].x.col(node);
}

physics::PointSpring Pull(int thread, int node, const Vec3& from, const Vec3& dir, double force_n) {
  physics::PointSpring s;
  s.target = physics::PointContact::Target::kThread;
  s.index = thread;
  s.nodes = {node, -1, -1, -1};
  s.weights = {1, 0, 0, 0};
  s.anchor_mm = from + kPullLeverMm * dir;
  s.stiffness_n_per_mm = force_n / kPullLeverMm;
  return s;
}

}  // namespace

std::vector<KnotRef> FindKnots(const State& state) {
  std::vector<KnotRef> knots;
  for (const SpringConstraint& c : state.constraints) {  // sorted by id: seat springs first
    if (c.tag != kKnotTag || c.a.kind != ConstraintEnd::Kind::kThread ||
        c.b.kind != ConstraintEnd::Kind::kThread)
      continue;
    auto it = std::find_if(knots.begin(), knots.end(), [&](const KnotRef& k) {
      return k.thread_a == c.a.index && k.thread_b == c.b.index;
    });
    if (it == knots.end()) {
      KnotRef k;
      k.id = c.id;
      k.thread_a = c.a.index;
      k.thread_b = c.b.index;
      k.node_a = c.a.nodes[0];
      k.node_b = c.b.nodes[0];
      knots.push_back(k);
      it = knots.end() - 1;
    }
    it->springs.push_back(c.id);
  }
  return knots;
}

int TissueSideNode(const State& state, int thread) {
  int node = 0;
  for (const SpringConstraint& c : state.constraints) {
    if (c.tag != "stitch") continue;
    for (const ConstraintEnd* e : {&c.a, &c.b})
      if (e->kind == ConstraintEnd::Kind::kThread && e->index == thread)
        node = std::max(node, static_cast<int>(e->nodes[0]));
  }
  return node;
}

double KnotSlipMm(const Model& model, const State& state, const KnotRef& knot) {
  const int threads = static_cast<int>(state.threads.size());
  const auto valid = [&](int t, int n) {
    return t >= 0 && t < threads && n >= 1 &&
           n < state.threads[static_cast<std::size_t>(t)].x.cols();
  };
  if (!valid(knot.thread_a, knot.node_a) || !valid(knot.thread_b, knot.node_b))
    throw std::invalid_argument("KnotSlipMm: knot threads or nodes out of range");
  const KnotPusherOptions& opt = model.operations.knot_pusher;
  // The copy: threads and this knot's springs only.
  State copy;
  copy.threads = state.threads;
  for (const SpringConstraint& c : state.constraints)
    if (std::binary_search(knot.springs.begin(), knot.springs.end(), c.id))
      copy.constraints.push_back(c);
  physics::ThreadWorkspace ws;
  ws.params = model.thread_solver;
  physics::InitThreadWorkspace(model.threads, &ws);
  const int below_a = knot.node_a - 1, below_b = knot.node_b - 1;
  Vec3 dir = Node(copy, knot.thread_a, below_a) - Node(copy, knot.thread_b, below_b);
  if (!(dir.norm() > 1e-9))
    dir = Node(copy, knot.thread_a, knot.node_a) - Node(copy, knot.thread_b, knot.node_b);
  if (!(dir.norm() > 1e-9)) dir = Vec3::UnitX();
  dir.normalize();
  const auto seat_gap = [&] {
    return (Node(copy, knot.thread_a, knot.node_a) - Node(copy, knot.thread_b, knot.node_b)).norm();
  };
  const double initial = seat_gap();
  const int steps =
      std::max(2, static_cast<int>(std::ceil(opt.pull_time_s / model.options.dt_s - 1e-9)));
  physics::ContactSet contacts;
  physics::SpringSet springs;
  double last = initial, before_last = initial;
  for (int k = 0; k < steps; ++k) {
    physics::BuildPointSprings(copy, &springs);
    springs.push_back(
        Pull(knot.thread_a, below_a, Node(copy, knot.thread_a, below_a), dir, opt.pull_force_n));
    springs.push_back(
        Pull(knot.thread_b, below_b, Node(copy, knot.thread_b, below_b), -dir, opt.pull_force_n));
    physics::StepThreads(model.threads, model.options.dt_s, model.options.gravity_mm_s2, &contacts,
                         &springs, &copy.threads, &ws);
    before_last = last;
    last = seat_gap();
  }
  return 0.5 * (last + before_last) - initial;
}

}  // namespace arthrosim::instruments
