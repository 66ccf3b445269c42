#pragma once
// Records what a source applied, step by step, in the session CSV format. Rows carry the step
// times, so replaying the file with RecordedSource at the same dt reproduces every InputFrame
// bit for bit (resampling is then the identity).
#include <cstdio>
#include <memory>
#include <string>

#include "arthrosim/input/input_source.h"

namespace arthrosim::input {

/// Appends frames to a session CSV, one line per device per step, flushed every step so that a
/// crash leaves at most a truncated last line (which the reader drops with a warning).
class SessionCsvWriter {
 public:
  /// Creates/truncates `path` and writes the header; InputError if it cannot.
  SessionCsvWriter(const std::string& path, const Model& model);
  ~SessionCsvWriter();
  SessionCsvWriter(const SessionCsvWriter&) = delete;
  SessionCsvWriter& operator=(const SessionCsvWriter&) = delete;
  /// Writes the three rows of `frame` at time t_s (s).
  void Write(double t_s, const InputFrame& frame);

 private:
  const Model& model_;
  std::string path_;
  std::FILE* file_ = nullptr;
};

/// Wraps a source and records every frame it produces (`--record session.csv`).
class RecordingSource : public InputSource {
 public:
  RecordingSource(std::unique_ptr<InputSource> inner, const std::string& path, const Model& model)
      : inner_(std::move(inner)), writer_(path, model) {}
  void Frame(std::int64_t step, double t_s, InputFrame* out) override {
    inner_->Frame(step, t_s, out);
    writer_.Write(t_s, *out);
  }
  void Feedback(const FeedbackFrame& f) override { inner_->Feedback(f); }
  void Notify(const std::string& text, double t_s) override { inner_->Notify(text, t_s); }
  bool Finished(double t_s) const override { return inner_->Finished(t_s); }
  double RealtimeLagS() const override { return inner_->RealtimeLagS(); }
  void SaveControllers(State* state) const override { inner_->SaveControllers(state); }
  void RestoreControllers(const State& state) override { inner_->RestoreControllers(state); }
  InputSource* inner() { return inner_.get(); }

 private:
  std::unique_ptr<InputSource> inner_;
  SessionCsvWriter writer_;
};

}  // namespace arthrosim::input
