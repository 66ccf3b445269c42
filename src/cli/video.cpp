#include "video.h"

#include <cstdlib>
#include <limits>
#include <utility>

#include "arthrosim/core/error.h"

namespace arthrosim::cli {
namespace {

render::RenderOptions ToOptions(const VideoArgs& a) {
  render::RenderOptions o;
  try {
    o.view = render::ParseView(a.view);
  } catch (const std::exception& e) {
    throw InputError("", 0, "--view", e.what());
  }
  const auto x = a.size.find('x');
  try {
    if (x == std::string::npos) throw std::invalid_argument("no x");
    std::size_t used_w = 0, used_h = 0;
    o.width = std::stoi(a.size.substr(0, x), &used_w);
    o.height = std::stoi(a.size.substr(x + 1), &used_h);
    if (used_w != x || used_h != a.size.size() - x - 1) throw std::invalid_argument("junk");
  } catch (const std::exception&) {
    throw InputError("", 0, "--size", "expected WIDTHxHEIGHT, e.g. 640x480, got '" + a.size + "'");
  }
  o.fps = a.fps;
  o.frames_dir = a.frames_dir;
  o.from_s = a.from_s;
  o.to_s = a.to_s < 0 ? std::numeric_limits<double>::infinity() : a.to_s;
  try {
    render::ValidateRenderOptions(o);
  } catch (const std::invalid_argument& e) {
    throw InputError("", 0, "render options", e.what());
  }
  return o;
}

}  // namespace

void AddVideoOptions(CLI::App* cmd, VideoArgs* a, bool with_video) {
  if (with_video) cmd->add_option("--video", a->video, "Also render an MP4 (H.264) while running");
  cmd->add_option("--view", a->view, "scope | overview | both")->capture_default_str();
  cmd->add_option("--size", a->size, "Frame size WIDTHxHEIGHT")->capture_default_str();
  cmd->add_option("--fps", a->fps, "Video frame rate")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  cmd->add_option("--frames", a->frames_dir, "Write PNG frames to this folder instead of MP4");
  cmd->add_option("--from", a->from_s, "First time to render, s")->check(CLI::NonNegativeNumber);
  cmd->add_option("--to", a->to_s, "Last time to render, s")->check(CLI::NonNegativeNumber);
}

VideoOutput::VideoOutput(const Model& model, const VideoArgs& args,
                         render::OverlayTextFn overlay_text) {
  const render::RenderOptions options = ToOptions(args);
  // One llvmpipe rasteriser thread unless the user chose: images are then reproducible.
  setenv("LP_NUM_THREADS", "1", 0);
  renderer_ = std::make_unique<render::Renderer>();
  sink_ = render::MakeSink(options, args.video);
  sequence_ = std::make_unique<render::SequenceRenderer>(model, options, renderer_.get(),
                                                         sink_.get(), std::move(overlay_text));
}

VideoOutput::~VideoOutput() = default;

}  // namespace arthrosim::cli
