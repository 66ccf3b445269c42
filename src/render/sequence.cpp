#include "arthrosim/render/sequence.h"

#include <cmath>
#include <stdexcept>

namespace arthrosim::render {
namespace {

constexpr double kTimeTolS = 1e-9;

}  // namespace

void ValidateRenderOptions(const RenderOptions& o) {
  if (o.width < 16 || o.height < 16 || o.width > 8192 || o.height > 8192) {
    throw std::invalid_argument("render width/height: expected 16..8192 pixels");
  }
  if (o.frames_dir.empty() && (o.width % 2 != 0 || o.height % 2 != 0)) {
    throw std::invalid_argument("render width/height: video needs even sizes (yuv420p)");
  }
  if (!(o.fps > 0) || o.fps > 1000) throw std::invalid_argument("render fps: expected (0, 1000]");
  if (!std::isfinite(o.from_s) || o.from_s < 0) {
    throw std::invalid_argument("render from: expected a finite time >= 0 s");
  }
  if (!(o.to_s >= o.from_s)) throw std::invalid_argument("render to: expected >= from");
}

std::unique_ptr<FrameSink> MakeSink(const RenderOptions& options, const std::string& video_path,
                                    const FfmpegOptions& ffmpeg) {
  if (!options.frames_dir.empty()) return std::make_unique<PngDirSink>(options.frames_dir);
  return std::make_unique<FfmpegSink>(video_path, options.width, options.height, options.fps,
                                      ffmpeg);
}

void StepOverlayText(const std::vector<StepSpan>& steps, double t_s, Overlay* overlay) {
  std::size_t current = steps.size();
  for (std::size_t i = 0; i < steps.size(); ++i) {
    const double start = steps[i].start_s;
    if (!(start <= t_s)) continue;  // NaN: never started
    if (current == steps.size() || start >= steps[current].start_s) current = i;
  }
  if (current == steps.size()) return;
  const StepSpan& s = steps[current];
  overlay->plan_step =
      "step " + std::to_string(current + 1) + "/" + std::to_string(steps.size()) + ": " + s.title;
  overlay->verdict = s.end_s <= t_s ? "done" : "in progress";
}

SequenceRenderer::SequenceRenderer(const Model& model, const RenderOptions& options,
                                   Renderer* renderer, FrameSink* sink, OverlayTextFn overlay_text)
    : model_(model),
      options_(options),
      renderer_(renderer),
      sink_(sink),
      overlay_text_(std::move(overlay_text)) {
  ValidateRenderOptions(options);
}

double SequenceRenderer::FrameTime(std::int64_t k) const {
  // from k, not by accumulation, so long runs do not drift
  return options_.from_s + static_cast<double>(k) / options_.fps;
}

void SequenceRenderer::EmitUntil(double t_end, bool inclusive) {
  if (!held_) return;
  Scene scene;
  bool built = false;
  ViewSpec spec;
  spec.view = options_.view;
  spec.width = options_.width;
  spec.height = options_.height;
  for (;;) {
    const double t = FrameTime(frames_);
    // times within kTimeTolS count as equal: a state at 0.1 * 6 s is the state "at 0.6 s"
    if (t > options_.to_s + kTimeTolS) break;
    if (inclusive ? t > t_end + kTimeTolS : t + kTimeTolS >= t_end) break;
    if (!built) {
      // one scene per held state, however many frames show it
      scene = BuildScene(model_, *held_);
      if (overlay_text_) overlay_text_(*held_, &scene.overlay);
      built = true;
    }
    renderer_->Render(scene, spec, &image_);
    sink_->Write(image_);
    ++frames_;
  }
}

void SequenceRenderer::Push(const State& state) {
  if (held_ && !(state.time_s > held_->time_s)) {
    throw std::invalid_argument("render: state times must increase (got " +
                                std::to_string(state.time_s) + " s after " +
                                std::to_string(held_->time_s) + " s)");
  }
  // frames before the first state show the first state (they are emitted with it)
  if (held_) EmitUntil(state.time_s, false);
  held_ = state;
}

void SequenceRenderer::Finish() {
  EmitUntil(held_ ? held_->time_s : 0.0, true);
  sink_->Close();
}

}  // namespace arthrosim::render
