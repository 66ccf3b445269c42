// Knot pusher: Choi et al. 2020 section III.6 and Fig. 9. Button 1 attaches threads to the tool
// (the nearest thread node within Dist_limit, one thread at a time, two at most); with two
// attached the knot pusher throws a half hitch in the limbs beyond the held nodes and, if the
// limbs then hold a real knot (IdentifyKnot), binds them with knot springs. Button 2 slides the
// knot down the limbs toward the target (the node operations.knot_pusher.target_node out from
// the tissue side) as the tool pushes slack into the loop below it; once there the tool lets go
// and the knot holds the loop. docs/operations.md "Knot tying".
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <string>

#include "arthrosim/core/soft_nodes.h"
#include "arthrosim/instruments/knot_identify.h"
#include "arthrosim/instruments/knot_pusher.h"
#include "arthrosim/physics/constraints.h"
#include "suture_ops.h"

namespace arthrosim::instruments {
namespace {

constexpr int kCurveSamples = 720;  // samples of the closed half-hitch curve
// A limb slides through the knot only while the loop below pulls on it with less than this (N):
// a loop drawn this tight stops the pusher.
constexpr double kSlideForceN = 10.0;

// A thread node held by the tool: the spring's id, thread and node.
struct Held {
  std::int64_t id = -1;
  int thread = -1;
  int node = -1;
};

std::vector<Held> HeldThreads(const State& state, int slot) {
  std::vector<Held> held;
  for (const SpringConstraint& c : state.constraints)
    if (c.tag == kKnotPusherTag && c.a.kind == ConstraintEnd::Kind::kTool && c.a.index == slot)
      held.push_back({c.id, c.b.index, c.b.nodes[0]});
  return held;
}

SpringConstraint* Mutable(State* state, std::int64_t id) {
  for (SpringConstraint& c : state->constraints)
    if (c.id == id) return &c;
  return nullptr;
}

// Rest spacing of a thread's nodes (its initial length over its segments), mm.
double NodeSpacingMm(const Model& model, int thread) {
  const Points& p = model.threads[static_cast<std::size_t>(thread)].initial.nodes;
  double arc = 0;
  for (int k = 1; k < p.cols(); ++k) arc += (p.col(k) - p.col(k - 1)).norm();
  return p.cols() > 1 ? arc / static_cast<double>(p.cols() - 1) : 1.0;
}

bool Alive(const ThreadState& th, int n) {
  return th.node_alive.empty() || th.node_alive[static_cast<std::size_t>(n)] != 0;
}

bool IsFixed(const Model& model, int thread, int node) {
  const std::vector<std::int32_t>& f = model.threads[static_cast<std::size_t>(thread)].fixed_nodes;
  return std::binary_search(f.begin(), f.end(), node);
}

// Nodes from the tissue side to the free end (stops at the first dead node).
std::vector<Vec3> Limb(const State& state, int thread) {
  const ThreadState& th = state.threads[static_cast<std::size_t>(thread)];
  std::vector<Vec3> limb;
  for (int n = TissueSideNode(state, thread); n < th.x.cols() && Alive(th, n); ++n)
    limb.push_back(th.x.col(n));
  return limb;
}

// Button 1 with fewer than two threads held: the nearest live, free node within dist_limit of
// the tool tip on a thread not held yet is tied to the tool. Event `thread_catch`.
void AttachThread(const Model& model, int slot, const std::vector<Held>& held, State* state) {
  const KnotPusherOptions& opt = model.operations.knot_pusher;
  const Vec3 tip = state->tools[static_cast<std::size_t>(slot)].pose.position_mm;
  std::vector<bool> taken(state->threads.size(), false);
  for (const Held& h : held) taken[static_cast<std::size_t>(h.thread)] = true;
  const CaughtNode c = CatchNearestThreadNode(model, slot, tip, opt.dist_limit_mm, taken,
                                              opt.thread_stiffness_n_per_mm, kKnotPusherTag, state);
  if (c.thread < 0) return;
  char detail[112];
  std::snprintf(detail, sizeof detail, "constraint=%lld node=%d distance_mm=%.3f held=%d",
                static_cast<long long>(c.constraint), c.node, c.distance_mm,
                static_cast<int>(held.size()) + 1);
  RecordEvent(model, slot, "thread_catch", model.threads[static_cast<std::size_t>(c.thread)].name,
              detail, state->threads[static_cast<std::size_t>(c.thread)].x.col(c.node), state);
}

// The closed half-hitch curve: a trefoil (sin t + 2 sin 2t, cos t - 2 cos 2t, -sin 3t) sampled
// from its lowest point (t0 = acos(1/8), a maximum of the second coordinate, which maps to -up);
// its lobe tip at t = pi is the top. Returns local coordinates with the bottom at the origin:
// (up, across, depth), unit scale.
std::vector<Vec3> HalfHitchCurve(int* top) {
  const double pi = std::numbers::pi, t0 = std::acos(1.0 / 8.0);
  const auto at = [](double t) {
    return Vec3(std::sin(t) + 2 * std::sin(2 * t), std::cos(t) - 2 * std::cos(2 * t),
                -std::sin(3 * t));
  };
  const Vec3 bottom = at(t0);
  std::vector<Vec3> curve;
  for (int k = 0; k < kCurveSamples; ++k) {
    const Vec3 p = at(t0 + 2 * pi * k / kCurveSamples) - bottom;
    curve.push_back(Vec3(-p.y(), -p.x(), p.z()));
  }
  *top = static_cast<int>(std::lround((pi - t0) / (2 * pi) * kCurveSamples));
  return curve;
}

// Points at arc lengths start, start + spacing, ... <= stop along the polyline.
std::vector<Vec3> Resample(const std::vector<Vec3>& line, double start, double spacing,
                           double stop) {
  std::vector<Vec3> out;
  double arc = 0, want = start;
  for (std::size_t k = 1; k < line.size() && want <= stop; ++k) {
    const double len = (line[k] - line[k - 1]).norm();
    while (want <= arc + len && want <= stop) {
      out.push_back(line[k - 1] + (line[k] - line[k - 1]) * ((want - arc) / std::max(len, 1e-12)));
      want += spacing;
    }
    arc += len;
  }
  return out;
}

double Length(const std::vector<Vec3>& line) {
  double arc = 0;
  for (std::size_t k = 1; k < line.size(); ++k) arc += (line[k] - line[k - 1]).norm();
  return arc;
}

// One limb's part of the half hitch in world coordinates: from the bottom along the curve in
// direction `dir` (+1 / -1) to the top, skipping `gap` mm at both ends, every `spacing` mm.
std::vector<Vec3> HitchPath(const std::vector<Vec3>& curve, int top, int dir, const Vec3& seat,
                            const Mat3& frame, double scale, double gap, double spacing) {
  std::vector<Vec3> line;
  const int n = static_cast<int>(curve.size());
  for (int k = 0;; k = (k + dir + n) % n) {
    line.push_back(seat + frame * (scale * curve[static_cast<std::size_t>(k)]));
    if (k == top) break;
  }
  return Resample(line, gap, spacing, Length(line) - gap);
}

// A path of exactly `segments` segments of `spacing` from `from` to `to` (|to - from| <=
// segments * spacing): a V bowed along `side` whose two legs make up the length, resampled.
std::vector<Vec3> LoopPath(const Vec3& from, const Vec3& to, int segments, double spacing,
                           const Vec3& side) {
  const double chord = (to - from).norm(), half = 0.5 * segments * spacing;
  const double bow = std::sqrt(std::max(0.0, half * half - 0.25 * chord * chord));
  const Vec3 along = chord > 1e-9 ? Vec3((to - from) / chord) : Vec3::UnitZ();
  Vec3 normal = side - side.dot(along) * along;
  normal = normal.norm() > 1e-6 ? Vec3(normal.normalized()) : along.unitOrthogonal();
  const std::vector<Vec3> v{from, 0.5 * (from + to) + bow * normal, to};
  std::vector<Vec3> out = Resample(v, 0, spacing, Length(v) + 1e-9);
  out.resize(static_cast<std::size_t>(segments) + 1, to);
  out.back() = to;
  return out;
}

// A knot laid by LayHalfHitch: the knot (seat) node and the top node (held by the tool) of each
// limb.
struct Laid {
  std::array<int, 2> seat{-1, -1};
  std::array<int, 2> top{-1, -1};
};

// Throws a half hitch: each limb is re-laid from its tissue side: the loop (a bowed V of whole
// rest segments) to the bottom of the knot, which sits in front of the pusher tip (tool +z), one
// side of the half-hitch curve each (A one way round, B the other), the tails spread back past
// the pusher. Every segment at most its rest length. False (nothing changed) if a limb is too
// short or a node to move is dead or fixed.
bool LayHalfHitch(const Model& model, int slot, const Held& a, const Held& b, State* state,
                  Laid* laid) {
  const KnotPusherOptions& opt = model.operations.knot_pusher;
  const Pose& pose = state->tools[static_cast<std::size_t>(slot)].pose;
  const Vec3 forward = pose.orientation * Vec3::UnitZ(), up = -forward;
  const std::array<const Held*, 2> limb{&a, &b};
  const Vec3 pa = state->threads[static_cast<std::size_t>(a.thread)].x.col(a.node);
  const Vec3 pb = state->threads[static_cast<std::size_t>(b.thread)].x.col(b.node);
  Vec3 across = (pb - pa) - (pb - pa).dot(up) * up;  // A takes the -across side
  if (!(across.norm() > 1e-6)) across = up.unitOrthogonal();
  across.normalize();
  Mat3 frame;
  frame << up, across, up.cross(across);
  int top = 0;
  const std::vector<Vec3> curve = HalfHitchCurve(&top);
  const double scale = opt.knot_size_mm, gap = 0.5 * opt.knot_size_mm;
  // The top lobe on the tool axis, 1 mm in front of the tip.
  const Vec3 top_local = scale * curve[static_cast<std::size_t>(top)];
  const Vec3 seat = pose.position_mm + (top_local.x() + 1.0) * forward -
                    frame * Vec3(0, top_local.y(), top_local.z());
  std::array<std::vector<Vec3>, 2> nodes;
  for (int s = 0; s < 2; ++s) {
    const Held& h = *limb[static_cast<std::size_t>(s)];
    const double spacing = NodeSpacingMm(model, h.thread);
    const ThreadState& th = state->threads[static_cast<std::size_t>(h.thread)];
    const int base = TissueSideNode(*state, h.thread);
    const std::vector<Vec3> hitch =
        HitchPath(curve, top, s == 0 ? -1 : 1, seat, frame, scale, gap, spacing);
    const Vec3 from = th.x.col(base);
    const int loop =
        std::max(1, static_cast<int>(std::ceil((hitch.front() - from).norm() / spacing - 1e-9)));
    std::vector<Vec3>& p = nodes[static_cast<std::size_t>(s)];
    p = LoopPath(from, hitch.front(), loop, spacing, -forward.cross(across).normalized());
    p.insert(p.end(), hitch.begin() + 1, hitch.end());
    if (base + static_cast<int>(p.size()) + 2 > th.x.cols()) return false;
    for (int n = base + 1; n < th.x.cols(); ++n)
      if (!Alive(th, n) || IsFixed(model, h.thread, n)) return false;
    laid->seat[static_cast<std::size_t>(s)] = base + loop;
    laid->top[static_cast<std::size_t>(s)] = base + static_cast<int>(p.size()) - 1;
  }
  for (int s = 0; s < 2; ++s) {
    const Held& h = *limb[static_cast<std::size_t>(s)];
    const double spacing = NodeSpacingMm(model, h.thread);
    const Vec3 out = (up + (s == 0 ? -1.5 : 1.5) * across).normalized();
    ThreadState& th = state->threads[static_cast<std::size_t>(h.thread)];
    const int base = TissueSideNode(*state, h.thread);
    const std::vector<Vec3>& p = nodes[static_cast<std::size_t>(s)];
    for (int n = base + 1; n < th.x.cols(); ++n) {
      const std::size_t j = static_cast<std::size_t>(n - base);
      th.x.col(n) = j < p.size() ? p[j] : Vec3(th.x.col(n - 1) + spacing * out);
      th.v.col(n).setZero();
    }
  }
  return true;
}

// Tool spring `id` moves to `node` of its thread, at the tool-frame point where it now is.
void ReanchorToolSpring(int slot, std::int64_t id, int node, State* state) {
  const Pose& pose = state->tools[static_cast<std::size_t>(slot)].pose;
  SpringConstraint* c = Mutable(state, id);
  c->b.nodes[0] = node;
  const Vec3 p = state->threads[static_cast<std::size_t>(c->b.index)].x.col(node);
  c->a.offset_mm = pose.orientation.conjugate() * (p - pose.position_mm);
}

bool KnotBetween(const State& state, int thread_a, int thread_b) {
  for (const KnotRef& k : FindKnots(state))
    if ((k.thread_a == thread_a && k.thread_b == thread_b) ||
        (k.thread_a == thread_b && k.thread_b == thread_a))
      return true;
  return false;
}

// With two threads held and no knot between them yet: throw the half hitch, identify, and only
// for a real knot bind the limbs (knot springs, node by node along the hitch) and record `knot`.
void TieKnot(const Model& model, int slot, Held a, Held b, State* state) {
  const KnotPusherOptions& opt = model.operations.knot_pusher;
  Laid laid;
  const bool thrown = LayHalfHitch(model, slot, a, b, state, &laid);
  if (thrown) {
    ReanchorToolSpring(slot, a.id, laid.top[0], state);
    ReanchorToolSpring(slot, b.id, laid.top[1], state);
    a.node = laid.seat[0];
    b.node = laid.seat[1];
  }
  const KnotIdentification id = IdentifyKnot(Limb(*state, a.thread), Limb(*state, b.thread));
  if (id.type == KnotType::kNone || id.type == KnotType::kUnknown) return;
  const ThreadState& ta = state->threads[static_cast<std::size_t>(a.thread)];
  const ThreadState& tb = state->threads[static_cast<std::size_t>(b.thread)];
  // The knot springs: first the seat spring between the knot nodes, then every pair of nodes of
  // the two limbs' hitch parts (knot node to held node) within 3 x knot_size of each other, so
  // the knot keeps its shape as a whole (only the knot nodes if the limbs were knotted some other
  // way).
  std::vector<std::pair<int, int>> pairs{{a.node, b.node}};
  if (thrown)
    for (int i = a.node; i <= laid.top[0]; ++i)
      for (int j = b.node; j <= laid.top[1]; ++j)
        if ((i != a.node || j != b.node) &&
            (ta.x.col(i) - tb.x.col(j)).norm() <= 3 * opt.knot_size_mm)
          pairs.emplace_back(i, j);
  std::int64_t seat_id = -1;
  int springs = 0;
  for (const auto& [i, j] : pairs) {
    SpringConstraint c;
    c.tag = kKnotTag;
    c.a.kind = c.b.kind = ConstraintEnd::Kind::kThread;
    c.a.index = a.thread;
    c.b.index = b.thread;
    c.a.nodes[0] = i;
    c.b.nodes[0] = j;
    c.a.weights[0] = c.b.weights[0] = 1;
    c.stiffness_n_per_mm = opt.knot_stiffness_n_per_mm;
    c.rest_length_mm = (ta.x.col(i) - tb.x.col(j)).norm();
    const std::int64_t sid = physics::AddConstraint(state, std::move(c));
    if (seat_id < 0) seat_id = sid;
    ++springs;
  }
  const Vec3 seat = 0.5 * (ta.x.col(a.node) + tb.x.col(b.node));
  char detail[320];
  std::snprintf(detail, sizeof detail,
                "knot=%lld type=%s crossings=%d writhe=%d half_hitches=%d votes=%d/%d "
                "thread_a=%s node_a=%d thread_b=%s node_b=%d springs=%d",
                static_cast<long long>(seat_id), KnotTypeName(id.type), id.crossings, id.writhe,
                id.half_hitches, id.votes, id.projections,
                model.threads[static_cast<std::size_t>(a.thread)].name.c_str(), a.node,
                model.threads[static_cast<std::size_t>(b.thread)].name.c_str(), b.node, springs);
  RecordEvent(model, slot, "knot", model.threads[static_cast<std::size_t>(a.thread)].name, detail,
              seat, state);
}

// Nodes of a limb from its knot node to its free end are movable (alive, not fixed).
bool Movable(const Model& model, const State& state, int thread, int from) {
  const ThreadState& th = state.threads[static_cast<std::size_t>(thread)];
  for (int k = from; k < th.x.cols(); ++k)
    if (!Alive(th, k) || IsFixed(model, thread, k)) return false;
  return true;
}

// Knot and tool springs on `thread`'s nodes from `from` up move down one node with them.
void ShiftSprings(int thread, int from, State* state) {
  for (SpringConstraint& c : state->constraints) {
    if (c.tag != kKnotTag && c.tag != kKnotPusherTag) continue;
    for (ConstraintEnd* e : {&c.a, &c.b})
      if (e->kind == ConstraintEnd::Kind::kThread && e->index == thread && e->nodes[0] >= from)
        e->nodes[0] -= 1;
  }
}

// Slides the knot one node toward the tissue on the limbs flagged in `slide`: the knot as a
// whole (both limbs from their knot nodes to their free ends) moves by one rigid translation d,
// so its shape (and the strands' order in it) is kept; on a sliding limb the knot node then
// takes the place of the loop's last node (the loop loses a segment, the tail gains one), on the
// other it stays the knot node. d is the point nearest the mean of the loops' last segments for
// which every new junction segment (loop node to knot node) is at most its rest length (the
// intersection of two balls, by alternating projection), so no segment is stretched. Returns
// false (nothing changed) if there is no such d.
bool SlideKnot(const Model& model, const KnotRef& knot, std::array<bool, 2> slide, State* state) {
  const std::array<int, 2> thread{knot.thread_a, knot.thread_b};
  const std::array<int, 2> node{knot.node_a, knot.node_b};
  std::array<Vec3, 2> centre;
  std::array<double, 2> rest{};
  Vec3 d = Vec3::Zero();
  for (std::size_t s = 0; s < 2; ++s) {
    const Points& x = state->threads[static_cast<std::size_t>(thread[s])].x;
    const int below = node[s] - (slide[s] ? 2 : 1);
    if (below < TissueSideNode(*state, thread[s]) || node[s] + 1 >= x.cols() ||
        !Movable(model, *state, thread[s], below + 1))
      return false;
    centre[s] = x.col(below) - x.col(node[s]);
    rest[s] = NodeSpacingMm(model, thread[s]);
    if (slide[s]) d += 0.5 * Vec3(x.col(node[s] - 1) - x.col(node[s]));
  }
  for (int it = 0; it < 200; ++it)
    for (std::size_t s = 0; s < 2; ++s) {
      const Vec3 r = d - centre[s];
      if (r.norm() > rest[s]) d = centre[s] + r * (rest[s] / r.norm());
    }
  for (std::size_t s = 0; s < 2; ++s)
    if ((d - centre[s]).norm() > rest[s] * (1 + 1e-9)) return false;
  for (std::size_t s = 0; s < 2; ++s) {
    ThreadState& th = state->threads[static_cast<std::size_t>(thread[s])];
    const int n = static_cast<int>(th.x.cols()), k = node[s];
    if (!slide[s]) {
      for (int i = k; i < n; ++i) th.x.col(i) += d;
      continue;
    }
    const Vec3 tail = th.x.col(n - 1) - th.x.col(n - 2);
    for (int i = k - 1; i + 1 < n; ++i) {
      th.x.col(i) = th.x.col(i + 1) + d;
      th.v.col(i) = th.v.col(i + 1);
    }
    th.x.col(n - 1) = th.x.col(n - 2) + tail;
    ShiftSprings(thread[s], k, state);
  }
  return true;
}

// Slides the knot one node toward the tissue on one limb whose loop is slack by more than a
// tenth of a segment: the knot stays where it is, the limb's nodes from the knot node on move
// down one index (the thread runs up through the knot, the tail grows by one), and the loop is
// re-laid with one segment fewer along its old path drawn toward its chord until it is exactly
// that long. No segment is stretched. Returns false (nothing changed) if the loop is not slack.
bool SlideThroughSlackLoop(const Model& model, int thread, int knot_node, State* state) {
  ThreadState& th = state->threads[static_cast<std::size_t>(thread)];
  const int base = TissueSideNode(*state, thread), n = static_cast<int>(th.x.cols());
  const double spacing = NodeSpacingMm(model, thread);
  const int m = knot_node - base;
  if (m < 2 || knot_node + 1 >= n || !Movable(model, *state, thread, base + 1)) return false;
  const Vec3 from = th.x.col(base), to = th.x.col(knot_node);
  const double want = (m - 1) * spacing;
  if ((to - from).norm() > want - 0.1 * spacing) return false;
  std::vector<Vec3> old(static_cast<std::size_t>(m + 1)), path(old.size());
  for (int i = 0; i <= m; ++i) old[static_cast<std::size_t>(i)] = th.x.col(base + i);
  const auto blend = [&](double lambda) {
    for (int i = 0; i <= m; ++i)
      path[static_cast<std::size_t>(i)] = (1 - lambda) * old[static_cast<std::size_t>(i)] +
                                          lambda * (from + (to - from) * (double(i) / m));
    return Length(path);
  };
  double lo = 0, hi = 1;
  for (int it = 0; it < 60; ++it) {
    const double mid = 0.5 * (lo + hi);
    (blend(mid) > want ? lo : hi) = mid;
  }
  blend(hi);
  const std::vector<Vec3> loop = Resample(path, 0, spacing, want + 1e-9);
  const Vec3 tail = th.x.col(n - 1) - th.x.col(n - 2);
  for (int k = knot_node - 1; k + 1 < n; ++k) {
    th.x.col(k) = th.x.col(k + 1);
    th.v.col(k) = th.v.col(k + 1);
  }
  th.x.col(n - 1) = th.x.col(n - 2) + tail;
  for (int i = 1; i + 1 < m && i < static_cast<int>(loop.size()); ++i) {
    th.x.col(base + i) = loop[static_cast<std::size_t>(i)];
    th.v.col(base + i).setZero();
  }
  ShiftSprings(thread, knot_node, state);
  return true;
}

// Slides the knot one node toward the tissue on a limb whose loop is taut: the knot stays, the
// loop is re-laid straight from the knot with one segment fewer, and the tissue side of the
// limb (every node up to the tissue-side node, with the stitches that hold them) is drawn toward
// the knot by the difference (at most one segment): the stitch springs then pull the tissue
// after it. Not for a limb whose tissue side has a fixed node (an anchored end cannot move).
bool SlideThroughTautLoop(const Model& model, int thread, int knot_node, State* state) {
  ThreadState& th = state->threads[static_cast<std::size_t>(thread)];
  const int base = TissueSideNode(*state, thread), n = static_cast<int>(th.x.cols());
  const double spacing = NodeSpacingMm(model, thread);
  const int m = knot_node - base;
  if (m < 2 || knot_node + 1 >= n || !Movable(model, *state, thread, 0)) return false;
  const Vec3 to = th.x.col(knot_node);
  const Vec3 chord = to - th.x.col(base);
  const double length = chord.norm(), want = (m - 1) * spacing;
  if (!(length > want)) return false;
  const Vec3 dir = chord / length, shift = (length - want) * dir;
  for (int k = 0; k <= base; ++k) th.x.col(k) += shift;
  const Vec3 tail = th.x.col(n - 1) - th.x.col(n - 2);
  for (int k = knot_node - 1; k + 1 < n; ++k) {
    th.x.col(k) = th.x.col(k + 1);
    th.v.col(k) = th.v.col(k + 1);
  }
  th.x.col(n - 1) = th.x.col(n - 2) + tail;
  for (int i = 1; i + 1 < m; ++i) {
    th.x.col(base + i) = to - (m - 1 - i) * spacing * dir;
    th.v.col(base + i).setZero();
  }
  ShiftSprings(thread, knot_node, state);
  return true;
}

// Tension of the loop where it enters the knot (N): EA x strain of the segment below the knot
// node (negative when it is compressed, i.e. the loop is slack).
double LoopTensionN(const Model& model, const State& state, int thread, int knot_node) {
  const Points& x = state.threads[static_cast<std::size_t>(thread)].x;
  const double rest = NodeSpacingMm(model, thread);
  const double strain = (x.col(knot_node) - x.col(knot_node - 1)).norm() / rest - 1;
  return model.threads[static_cast<std::size_t>(thread)].stretch_stiffness_n * strain;
}

// Residual gap between the torn tendon edge and the footprint (mm): the smallest distance from
// a node of region `tendon_edge` to the box of region `footprint`; -1 if either is missing.
double EdgeToFootprintMm(const Model& model, const State& state) {
  const int edge = model.FindRegion("tendon_edge"), foot = model.FindRegion("footprint");
  if (edge < 0 || foot < 0) return -1;
  const Region& e = model.regions[static_cast<std::size_t>(edge)];
  const Region& f = model.regions[static_cast<std::size_t>(foot)];
  const int body = model.FindSoftBody(e.body);
  if (body < 0 || e.nodes.empty()) return -1;
  const SoftBodyState& tissue = state.soft_bodies[static_cast<std::size_t>(body)];
  const std::vector<std::uint8_t> in_tissue = NodesInAliveTets(tissue);  // skip cut-off debris
  double best = -1;
  for (const std::int32_t n : e.nodes) {
    if (!in_tissue[static_cast<std::size_t>(n)]) continue;
    const Vec3 p = tissue.x.col(n);
    const Vec3 q = p.cwiseMax(f.box_min_mm).cwiseMin(f.box_max_mm);
    const double d = (p - q).norm();
    if (best < 0 || d < best) best = d;
  }
  return best;
}

// Once the knot sits on the target nodes: the tool lets go, the pull test judges the knot, and
// `knot_seated` records where it is, how far from the target, the gap and the slip.
void SeatKnot(const Model& model, int slot, const KnotRef& knot, const std::vector<Held>& held,
              State* state) {
  const KnotPusherOptions& opt = model.operations.knot_pusher;
  const auto target = [&](int thread) {
    const ThreadState& th = state->threads[static_cast<std::size_t>(thread)];
    const int t = std::min<int>(TissueSideNode(*state, thread) + opt.target_node,
                                static_cast<int>(th.x.cols()) - 1);
    return Vec3(th.x.col(t));
  };
  const Vec3 xa = state->threads[static_cast<std::size_t>(knot.thread_a)].x.col(knot.node_a);
  const Vec3 xb = state->threads[static_cast<std::size_t>(knot.thread_b)].x.col(knot.node_b);
  const Vec3 at = 0.5 * (xa + xb);
  const double error_mm = (at - 0.5 * (target(knot.thread_a) + target(knot.thread_b))).norm();
  for (const Held& h : held) physics::RemoveConstraint(state, h.id);
  const double slip_mm = KnotSlipMm(model, *state, knot);
  const double gap_mm = EdgeToFootprintMm(model, *state);
  const KnotIdentification id =
      IdentifyKnot(Limb(*state, knot.thread_a), Limb(*state, knot.thread_b));
  char gap[48] = "";
  if (gap_mm >= 0) std::snprintf(gap, sizeof gap, " gap_mm=%.3f", gap_mm);
  char detail[384];
  std::snprintf(detail, sizeof detail,
                "knot=%lld type=%s votes=%d/%d thread_a=%s node_a=%d thread_b=%s node_b=%d "
                "target_error_mm=%.3f%s slip_mm=%.3f pull_force_n=%.3g pull_time_s=%.3g secure=%d",
                static_cast<long long>(knot.id), KnotTypeName(id.type), id.votes, id.projections,
                model.threads[static_cast<std::size_t>(knot.thread_a)].name.c_str(), knot.node_a,
                model.threads[static_cast<std::size_t>(knot.thread_b)].name.c_str(), knot.node_b,
                error_mm, gap, slip_mm, opt.pull_force_n, opt.pull_time_s,
                slip_mm <= opt.slip_limit_mm ? 1 : 0);
  RecordEvent(model, slot, "knot_seated",
              model.threads[static_cast<std::size_t>(knot.thread_a)].name, detail, at, state);
}

// Button 2 with both threads held and a knot between them: slide the knot one node toward
// the target on each limb not there yet; seat it once both limbs are there.
void PushKnot(const Model& model, int slot, const std::vector<Held>& held, State* state) {
  const KnotPusherOptions& opt = model.operations.knot_pusher;
  for (const KnotRef& knot : FindKnots(*state)) {
    const auto holds = [&](int thread) {
      return std::any_of(held.begin(), held.end(),
                         [&](const Held& h) { return h.thread == thread; });
    };
    if (!holds(knot.thread_a) || !holds(knot.thread_b)) continue;
    const bool there_a = knot.node_a <= TissueSideNode(*state, knot.thread_a) + opt.target_node;
    const bool there_b = knot.node_b <= TissueSideNode(*state, knot.thread_b) + opt.target_node;
    if (there_a && there_b) return SeatKnot(model, slot, knot, held, state);
    // The pusher keeps its hold where it is: it, not the slide, says where the knot goes. A
    // limb slides while its loop is slack or pulled less than kSlideForceN.
    const std::array<bool, 2> slide{
        !there_a && LoopTensionN(model, *state, knot.thread_a, knot.node_a) <= kSlideForceN,
        !there_b && LoopTensionN(model, *state, knot.thread_b, knot.node_b) <= kSlideForceN};
    // A slack loop runs up through the knot where it is; a taut one draws the knot down it.
    // A slack loop runs up through the knot where it is; taut loops draw the knot down them.
    bool slid = false;
    for (std::size_t s = 0; s < 2; ++s)
      if (slide[s] && SlideThroughSlackLoop(model, s == 0 ? knot.thread_a : knot.thread_b,
                                            s == 0 ? knot.node_a : knot.node_b, state))
        slid = true;
    if (slid) return;
    if (slide[0] && slide[1] && SlideKnot(model, knot, slide, state)) return;
    if (slide[0] && SlideKnot(model, knot, {true, false}, state)) return;
    if (slide[1] && SlideKnot(model, knot, {false, true}, state)) return;
    // Straight loops at an angle the knot cannot be drawn down: the loop pulls its tissue in.
    if (slide[0] && SlideThroughTautLoop(model, knot.thread_a, knot.node_a, state)) return;
    if (slide[1]) SlideThroughTautLoop(model, knot.thread_b, knot.node_b, state);
    return;
  }
}

}  // namespace

void KnotPusherOperation(const Model& model, int slot, const StepContext& /*context*/, State* state,
                         InstrumentScratch* /*scratch*/) {
  const ToolState& tool = state->tools[static_cast<std::size_t>(slot)];
  std::vector<Held> held = HeldThreads(*state, slot);
  if (Button1(tool) && held.size() < 2) {
    AttachThread(model, slot, held, state);
    const std::vector<Held> now = HeldThreads(*state, slot);
    if (now.size() == 2 && held.size() == 1 && !KnotBetween(*state, now[0].thread, now[1].thread))
      TieKnot(model, slot, now[0], now[1], state);
    held = HeldThreads(*state, slot);
  }
  if (Button2(tool) && held.size() == 2) PushKnot(model, slot, held, state);
}

}  // namespace arthrosim::instruments
