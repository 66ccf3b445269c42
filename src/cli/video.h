#pragma once
// Shared by `run --video` and `render`: parse the render options, open the renderer and sink.
#include <CLI/CLI.hpp>
#include <memory>
#include <string>

#include "arthrosim/core/model.h"
#include "arthrosim/render/sequence.h"

namespace arthrosim::cli {

/// The command-line form of RenderOptions (`--size WxH`, `--view`, ...).
struct VideoArgs {
  std::string video, frames_dir, view = "scope", size = "640x480";
  double fps = 25, from_s = 0, to_s = -1;
};

/// Adds --view --size --fps --frames --from --to (and --video if with_video) to cmd.
void AddVideoOptions(CLI::App* cmd, VideoArgs* a, bool with_video);

/// Renderer + sink + sequence for a run; Push states, then Finish.
class VideoOutput {
 public:
  /// `overlay_text` (optional) fills the overlay's step and verdict at each state.
  /// @throws InputError for bad options (field named), RenderError if OSMesa/ffmpeg fail.
  VideoOutput(const Model& model, const VideoArgs& args,
              render::OverlayTextFn overlay_text = nullptr);
  ~VideoOutput();
  void Push(const State& state) { sequence_->Push(state); }
  void Finish() { sequence_->Finish(); }
  std::int64_t frames() const { return sequence_->frames(); }

 private:
  std::unique_ptr<render::Renderer> renderer_;
  std::unique_ptr<render::FrameSink> sink_;
  std::unique_ptr<render::SequenceRenderer> sequence_;
};

}  // namespace arthrosim::cli
