// Knot queries and the knot security pull test (docs/operations.md "Knot tying"): no open
// simulator says whether a tied knot holds; this loads both limbs of a copy of the knot and
// measures how far it slips (clinically a knot that slips more than 3 mm has failed).
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

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

namespace {

// One knot thread's part in the pull test's copy: model nodes lo..hi become copy nodes 0..hi-lo.
struct PullSpan {
  int thread = -1;  // model thread index
  int lo = 0, hi = 0;
};

// The nodes of `thread` that the knot touches (knot springs, knot nodes, the pulled nodes)
// widened by `window_mm` of rest arc length on each side, clamped to the thread.
PullSpan SpanOf(const Model& model, const State& state, const KnotRef& knot, int thread,
                double window_mm) {
  PullSpan sp;
  sp.thread = thread;
  sp.lo = std::numeric_limits<int>::max();
  sp.hi = -1;
  const auto touch = [&](int node) {
    sp.lo = std::min(sp.lo, node);
    sp.hi = std::max(sp.hi, node);
  };
  if (knot.thread_a == thread) {
    touch(knot.node_a);
    touch(knot.node_a - 1);
  }
  if (knot.thread_b == thread) {
    touch(knot.node_b);
    touch(knot.node_b - 1);
  }
  for (const SpringConstraint& c : state.constraints) {
    if (!std::binary_search(knot.springs.begin(), knot.springs.end(), c.id)) continue;
    for (const ConstraintEnd* e : {&c.a, &c.b}) {
      if (e->kind != ConstraintEnd::Kind::kThread || e->index != thread) continue;
      for (std::int32_t n : e->nodes)
        if (n >= 0) touch(n);
    }
  }
  const Points& rest = model.threads[static_cast<std::size_t>(thread)].initial.nodes;
  const int n = static_cast<int>(rest.cols());
  double arc = 0;
  while (sp.lo > 0 && (arc += (rest.col(sp.lo) - rest.col(sp.lo - 1)).norm()) <= window_mm) --sp.lo;
  arc = 0;
  while (sp.hi + 1 < n && (arc += (rest.col(sp.hi + 1) - rest.col(sp.hi)).norm()) <= window_mm)
    ++sp.hi;
  return sp;
}

}  // namespace

double KnotSlipMm(const Model& model, const State& state, const KnotRef& knot, KnotPullWork* work,
                  double window_mm) {
  const int threads = static_cast<int>(state.threads.size());
  const auto valid = [&](int t, int n) {
    return t >= 0 && t < threads && n >= 1 &&
           n < state.threads[static_cast<std::size_t>(t)].x.cols();
  };
  if (!valid(knot.thread_a, knot.node_a) || !valid(knot.thread_b, knot.node_b))
    throw std::invalid_argument("KnotSlipMm: knot threads or nodes out of range");
  if (!(window_mm >= 0)) throw std::invalid_argument("KnotSlipMm: window_mm must be >= 0");
  for (const SpringConstraint& c : state.constraints) {
    if (!std::binary_search(knot.springs.begin(), knot.springs.end(), c.id)) continue;
    for (const ConstraintEnd* e : {&c.a, &c.b})
      if (e->kind != ConstraintEnd::Kind::kThread ||
          (e->index != knot.thread_a && e->index != knot.thread_b))
        throw std::invalid_argument("KnotSlipMm: knot spring " + std::to_string(c.id) +
                                    " does not join the knot's threads");
  }
  const KnotPusherOptions& opt = model.operations.knot_pusher;
  // The copy: the knot's thread(s), each cut to its span, and this knot's springs only.
  std::vector<PullSpan> spans = {SpanOf(model, state, knot, knot.thread_a, window_mm)};
  if (knot.thread_b != knot.thread_a)
    spans.push_back(SpanOf(model, state, knot, knot.thread_b, window_mm));
  const auto copy_index = [&](int thread) {
    return thread == knot.thread_a ? 0 : static_cast<int>(spans.size()) - 1;
  };
  std::vector<ThreadModel> piece_models;
  State copy;
  for (const PullSpan& sp : spans) {
    const ThreadModel& tm = model.threads[static_cast<std::size_t>(sp.thread)];
    const ThreadState& ts = state.threads[static_cast<std::size_t>(sp.thread)];
    const int len = sp.hi - sp.lo + 1;
    ThreadModel m = tm;
    m.initial.nodes = tm.initial.nodes.middleCols(sp.lo, len);
    m.initial.edges.clear();
    m.fixed_nodes.clear();
    for (std::int32_t f : tm.fixed_nodes)
      if (f >= sp.lo && f <= sp.hi) m.fixed_nodes.push_back(f - sp.lo);
    // Cut ends are left free, not fixed: a fixed end a few mm from the knot holds the limb
    // (the weak slab knot then slips 2.8 mm instead of 8.5 at a 5 mm window).
    piece_models.push_back(std::move(m));
    ThreadState piece;
    piece.x = ts.x.middleCols(sp.lo, len);
    piece.v = ts.v.middleCols(sp.lo, len);
    piece.node_alive.assign(ts.node_alive.begin() + sp.lo, ts.node_alive.begin() + sp.hi + 1);
    copy.threads.push_back(std::move(piece));
  }
  for (const SpringConstraint& c : state.constraints) {
    if (!std::binary_search(knot.springs.begin(), knot.springs.end(), c.id)) continue;
    SpringConstraint r = c;
    for (ConstraintEnd* e : {&r.a, &r.b}) {
      const int lo = spans[static_cast<std::size_t>(copy_index(e->index))].lo;
      e->index = copy_index(e->index);
      for (std::int32_t& n : e->nodes)
        if (n >= 0) n -= lo;
    }
    copy.constraints.push_back(r);
  }
  const int ta = copy_index(knot.thread_a), tb = copy_index(knot.thread_b);
  const int node_a = knot.node_a - spans[static_cast<std::size_t>(ta)].lo;
  const int node_b = knot.node_b - spans[static_cast<std::size_t>(tb)].lo;
  physics::ThreadWorkspace ws;
  ws.params = model.thread_solver;
  physics::InitThreadWorkspace(piece_models, &ws);
  const int below_a = node_a - 1, below_b = node_b - 1;
  Vec3 dir = Node(copy, ta, below_a) - Node(copy, tb, below_b);
  if (!(dir.norm() > 1e-9)) dir = Node(copy, ta, node_a) - Node(copy, tb, node_b);
  if (!(dir.norm() > 1e-9)) dir = Vec3::UnitX();
  dir.normalize();
  const auto seat_gap = [&] { return (Node(copy, ta, node_a) - Node(copy, tb, node_b)).norm(); };
  const double initial = seat_gap();
  const int steps =
      std::max(2, static_cast<int>(std::ceil(opt.pull_time_s / model.options.dt_s - 1e-9)));
  KnotPullWork done;  // counted on the copy itself: what StepThreads is given
  done.threads = static_cast<int>(copy.threads.size());
  for (const ThreadState& t : copy.threads) done.nodes += static_cast<int>(t.x.cols());
  physics::ContactSet contacts;
  physics::SpringSet springs;
  double last = initial, before_last = initial;
  for (int k = 0; k < steps; ++k) {
    physics::BuildPointSprings(copy, &springs);
    springs.push_back(Pull(ta, below_a, Node(copy, ta, below_a), dir, opt.pull_force_n));
    springs.push_back(Pull(tb, below_b, Node(copy, tb, below_b), -dir, opt.pull_force_n));
    physics::StepThreads(piece_models, model.options.dt_s, model.options.gravity_mm_s2, &contacts,
                         &springs, &copy.threads, &ws);
    ++done.steps;
    done.newton_iterations += ws.last.newton_iterations;
    before_last = last;
    last = seat_gap();
  }
  if (work) *work = done;
  return 0.5 * (last + before_last) - initial;
}

}  // namespace arthrosim::instruments
