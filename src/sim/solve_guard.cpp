// The divergence guard's pieces: keep, check, undo (include/arthrosim/sim/solve_guard.h).
#include "arthrosim/sim/solve_guard.h"

#include <fmt/core.h>

#include <cmath>

namespace arthrosim::sim {
namespace {

// Copies src into *dst keeping dst's storage when the sizes match.
void Keep(const Points& src, Points* dst) { *dst = src; }

// Puts back the first columns of *dst that `saved` holds (columns appended since stay).
void PutBack(const Points& saved, Points* dst) {
  const Eigen::Index n = std::min(saved.cols(), dst->cols());
  dst->leftCols(n) = saved.leftCols(n);
}

// Folds one node into *h: a non-finite node wins over any finite one, then the fastest.
void Visit(ConstraintEnd::Kind kind, std::int32_t body, std::int32_t node, const Vec3& x,
           const Vec3& v, SolveHealth* h) {
  const bool finite = x.allFinite() && v.allFinite();
  if (!finite) {
    if (h->finite) *h = SolveHealth{false, h->max_speed_mm_s, kind, body, node};
    return;
  }
  const double speed = v.norm();
  if (speed > h->max_speed_mm_s) {
    h->max_speed_mm_s = speed;
    if (h->finite) {
      h->kind = kind;
      h->body = body;
      h->node = node;
    }
  }
}

}  // namespace

void SaveSolveStart(const State& state, SolveStart* start) {
  const std::size_t nb = state.soft_bodies.size(), nt = state.threads.size();
  start->soft_x.resize(nb);
  start->soft_v.resize(nb);
  start->soft_dv_warm.resize(nb);
  for (std::size_t b = 0; b < nb; ++b) {
    const SoftBodyState& sb = state.soft_bodies[b];
    Keep(sb.x, &start->soft_x[b]);
    Keep(sb.v, &start->soft_v[b]);
    Keep(sb.dv_warm, &start->soft_dv_warm[b]);
  }
  start->thread_x.resize(nt);
  start->thread_v.resize(nt);
  for (std::size_t t = 0; t < nt; ++t) {
    Keep(state.threads[t].x, &start->thread_x[t]);
    Keep(state.threads[t].v, &start->thread_v[t]);
  }
}

void RestoreSolveStart(const SolveStart& start, State* state) {
  for (std::size_t b = 0; b < state->soft_bodies.size() && b < start.soft_x.size(); ++b) {
    SoftBodyState& sb = state->soft_bodies[b];
    PutBack(start.soft_x[b], &sb.x);
    PutBack(start.soft_v[b], &sb.v);
    PutBack(start.soft_dv_warm[b], &sb.dv_warm);
  }
  for (std::size_t t = 0; t < state->threads.size() && t < start.thread_x.size(); ++t) {
    PutBack(start.thread_x[t], &state->threads[t].x);
    PutBack(start.thread_v[t], &state->threads[t].v);
  }
}

SolveHealth CheckSolve(const State& state) {
  SolveHealth h;
  for (std::size_t b = 0; b < state.soft_bodies.size(); ++b) {
    const SoftBodyState& sb = state.soft_bodies[b];
    for (Eigen::Index n = 0; n < sb.x.cols() && n < sb.v.cols(); ++n) {
      Visit(ConstraintEnd::Kind::kSoftBody, static_cast<std::int32_t>(b),
            static_cast<std::int32_t>(n), sb.x.col(n), sb.v.col(n), &h);
    }
  }
  for (std::size_t t = 0; t < state.threads.size(); ++t) {
    const ThreadState& th = state.threads[t];
    for (Eigen::Index n = 0; n < th.x.cols() && n < th.v.cols(); ++n) {
      const auto i = static_cast<std::size_t>(n);
      if (i < th.node_alive.size() && !th.node_alive[i]) continue;  // cut away
      Visit(ConstraintEnd::Kind::kThread, static_cast<std::int32_t>(t),
            static_cast<std::int32_t>(n), th.x.col(n), th.v.col(n), &h);
    }
  }
  return h;
}

std::string WorstNodeBody(const Model& model, const SolveHealth& health) {
  if (health.body < 0) return "";
  const auto b = static_cast<std::size_t>(health.body);
  if (health.kind == ConstraintEnd::Kind::kSoftBody) {
    return b < model.soft_bodies.size() ? model.soft_bodies[b].name : "?";
  }
  return b < model.threads.size() ? model.threads[b].name : "?";
}

std::string DescribeWorstNode(const Model& model, const SolveHealth& health) {
  if (health.body < 0) return "no node";
  const bool soft = health.kind == ConstraintEnd::Kind::kSoftBody;
  const std::string what =
      health.finite ? fmt::format("at {:.3g} mm/s", health.max_speed_mm_s) : "not finite";
  return fmt::format("{} '{}' node {} {}", soft ? "soft body" : "thread",
                     WorstNodeBody(model, health), health.node, what);
}

}  // namespace arthrosim::sim
