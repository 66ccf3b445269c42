#pragma once
// Throughput figures for `arthrosim bench --render`.
#include <string>

#include "arthrosim/core/model.h"
#include "arthrosim/core/state.h"

namespace arthrosim::render {

/// The initial state of `model` with its first two instruments inserted in front of the scope
/// (tips 15-20 mm along the view direction, jaws half open, 2 N on slot 0), so a render
/// benchmark draws what a surgeon sees during a repair.
State MakeBenchmarkState(const Model& model);

/// Throughput of one measurement.
struct RenderThroughput {
  double fps = 0;                  ///< frames per wall-clock second
  double cpu_ms_per_frame = 0;     ///< CPU time of this process (all threads, llvmpipe included)
  double ffmpeg_ms_per_frame = 0;  ///< CPU time of the ffmpeg encoder process (0 without encoding)
};

/// Frames per second and CPU time per frame of BuildScene + Render (as MeasureRenderFps). The
/// CPU figures do not depend on what else runs on the machine, unlike fps.
RenderThroughput MeasureRender(const Model& model, const State& state, int width, int height,
                               int frames, bool with_encoding);

/// Frames per second of BuildScene + Render (scope view, overlay on) at width x height over
/// `frames` frames after two warm-up frames, wall clock; with_encoding adds the ffmpeg encode
/// (x264 veryfast, 2 threads) of every frame to a temporary MP4 that is deleted afterwards.
/// @throws RenderError if the renderer or ffmpeg is unavailable.
double MeasureRenderFps(const Model& model, const State& state, int width, int height, int frames,
                        bool with_encoding);

/// Lines for `arthrosim bench --render`: render_fps_640x480=, video_fps_640x480=,
/// render_fps_1280x720=, video_fps_1280x720= (one decimal), `frames` frames each, each followed
/// by its CPU milliseconds per frame (render_cpu_ms_WxH=, video_cpu_ms_WxH= own process, and
/// video_ffmpeg_cpu_ms_WxH=).
std::string RenderBenchReport(const Model& model, const State& state, int frames);

}  // namespace arthrosim::render
