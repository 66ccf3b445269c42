#pragma once
// `serve --plan` / `run --plan`: the plan's live evaluator driven from the run loop. After each
// step it observes the state (the frame too when the run file keeps one), and each warning due
// becomes a `live_warning` event in the State (so the run file records it), a STRING message to
// the device side through InputSource::Notify, and a line on stderr.
#include <memory>
#include <string>

#include "arthrosim/core/model.h"
#include "arthrosim/core/state.h"
#include "arthrosim/input/input_source.h"

namespace arthrosim::scoring {
class LiveEvaluator;
}

namespace arthrosim::cli {

class LiveFeedback {
 public:
  /// Loads the plan (strictly, against `model`). @throws InputError naming the plan file.
  LiveFeedback(const std::string& plan_path, const Model& model, bool print);
  ~LiveFeedback();
  /// Observes the initial state (frame 0 of the run file); warnings go through `source`.
  void Begin(const State& initial, input::InputSource* source);
  /// Observes the step just taken; `frame` = the run file keeps this step as a frame. Warnings
  /// due are appended to state->events and sent through `source`.
  void AfterStep(bool frame, State* state, input::InputSource* source);
  /// One summary line on stderr (warnings given and suppressed by type).
  void Finish() const;

 private:
  std::unique_ptr<scoring::LiveEvaluator> live_;
  bool print_;
};

}  // namespace arthrosim::cli
