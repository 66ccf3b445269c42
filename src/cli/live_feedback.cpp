#include "live_feedback.h"

#include <fmt/core.h>

#include "arthrosim/scoring/live.h"
#include "arthrosim/scoring/plan.h"

namespace arthrosim::cli {
namespace {

int Sum(const std::map<std::string, int>& by_type) {
  int n = 0;
  for (const auto& [type, k] : by_type) n += k;
  return n;
}

std::string Counts(const std::map<std::string, int>& by_type) {
  std::string s;
  for (const auto& [type, n] : by_type) s += fmt::format("{}{} {}", s.empty() ? "" : ", ", n, type);
  return s.empty() ? "none" : s;
}

}  // namespace

LiveFeedback::LiveFeedback(const std::string& plan_path, const Model& model, bool print)
    : live_(std::make_unique<scoring::LiveEvaluator>(scoring::LoadPlan(plan_path, &model), model)),
      print_(print) {}

LiveFeedback::~LiveFeedback() = default;

void LiveFeedback::Begin(const State& initial, input::InputSource* source) {
  // Frame 0 is in the file before any step: warnings there are sent and printed, not recorded
  // (nothing is inserted at t = 0 in practice).
  for (const scoring::LiveWarning& w : live_->Observe(initial, true)) {
    source->Notify(w.message, w.time_s);
    if (print_) fmt::print(stderr, "{}\n", w.message);
  }
}

void LiveFeedback::AfterStep(bool frame, State* state, input::InputSource* source) {
  for (const scoring::LiveWarning& w : live_->Observe(*state, frame)) {
    state->events.push_back(w.AsEvent());
    source->Notify(w.message, w.time_s);
    if (print_) fmt::print(stderr, "{}\n", w.message);
  }
}

void LiveFeedback::Finish() const {
  if (!print_) return;
  fmt::print(stderr, "live feedback: {} warning(s) given ({}); {} repeat(s) held back\n",
             Sum(live_->given()), Counts(live_->given()), Sum(live_->suppressed()));
}

}  // namespace arthrosim::cli
