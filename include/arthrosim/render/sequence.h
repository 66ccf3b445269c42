#pragma once
// Rendering a run: a stream of (Model, State) frames in increasing time, resampled to a fixed
// frame rate by sample-and-hold (frame k at t_k = from_s + k / fps shows the latest state with
// time <= t_k + 1e-9 s, so rounding in state times does not skip a state), rendered and handed
// to a FrameSink. Used by `arthrosim render` on States read
// from HDF5 and live during a run.
#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "arthrosim/core/model.h"
#include "arthrosim/core/state.h"
#include "arthrosim/render/renderer.h"
#include "arthrosim/render/video_sink.h"

namespace arthrosim::render {

/// Options of `arthrosim render` / `run --video`.
struct RenderOptions {
  View view = View::kScope;
  int width = 640;
  int height = 480;
  double fps = 25;
  std::string frames_dir;  ///< non-empty: write PNG frames here instead of a video
  double from_s = 0;       ///< first output time, s
  double to_s = std::numeric_limits<double>::infinity();  ///< last output time (inclusive), s
};

/// Checks the options. @throws std::invalid_argument naming the bad field.
void ValidateRenderOptions(const RenderOptions& options);

/// Sink for `options`: PngDirSink(frames_dir) if set, else FfmpegSink(video_path).
std::unique_ptr<FrameSink> MakeSink(const RenderOptions& options, const std::string& video_path,
                                    const FfmpegOptions& ffmpeg = {});

/// Text for the overlay's plan step and verdict at a state (scoring plugs in here).
using OverlayTextFn = std::function<void(const State&, Overlay*)>;

/// One procedure step as the video's overlay names it: its title and when it ran, s (start NaN =
/// never started; end NaN = never completed).
struct StepSpan {
  std::string title;
  double start_s = 0, end_s = 0;
};

/// The overlay text at time `t_s`: the step that started last at or before `t_s` as
/// "step i/N: title" in `plan_step`, and in `verdict` "in progress" before its end and "done"
/// from its end on (a step that never ends stays "in progress"). Before the first start both
/// stay empty. Ties in start time go to the later step of the list.
void StepOverlayText(const std::vector<StepSpan>& steps, double t_s, Overlay* overlay);

/// Streams states into frames. Push states in strictly increasing time_s, then Finish.
class SequenceRenderer {
 public:
  /// `model`, `renderer` and `sink` must outlive this object.
  SequenceRenderer(const Model& model, const RenderOptions& options, Renderer* renderer,
                   FrameSink* sink, OverlayTextFn overlay_text = nullptr);
  /// Emits the frames whose times fall before this state's time (they show the previous state).
  /// @throws std::invalid_argument if time does not increase.
  void Push(const State& state);
  /// Emits the remaining frames up to min(to_s, last state time) and closes the sink.
  void Finish();
  /// Frames emitted so far.
  std::int64_t frames() const { return frames_; }

 private:
  void EmitUntil(double t_end, bool inclusive);
  double FrameTime(std::int64_t k) const;

  const Model& model_;
  RenderOptions options_;
  Renderer* renderer_;
  FrameSink* sink_;
  OverlayTextFn overlay_text_;
  std::optional<State> held_;
  std::int64_t frames_ = 0;
  Image image_;
};

}  // namespace arthrosim::render
