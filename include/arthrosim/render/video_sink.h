#pragma once
// Frame sinks: an H.264 MP4 written by piping raw RGB frames to the ffmpeg program, or a
// directory of numbered PNG files. Piping keeps the GPL encoder and libav API churn out of the
// simulator; the encode is reproducible byte for byte for pinned threads (bitexact flags).
#include <cstdint>
#include <memory>
#include <string>

#include "arthrosim/render/image.h"

namespace arthrosim::render {

/// Receives frames of one fixed size in presentation order.
class FrameSink {
 public:
  virtual ~FrameSink() = default;
  /// Appends one frame. @throws RenderError on I/O failure or a size change.
  virtual void Write(const Image& frame) = 0;
  /// Finishes the output (idempotent). @throws RenderError if the encoder failed.
  virtual void Close() = 0;
  /// Frames written so far.
  virtual std::int64_t frames() const = 0;
};

/// Encoder settings for FfmpegSink.
struct FfmpegOptions {
  std::string program = "ffmpeg";   ///< looked up in PATH unless it contains '/'
  std::string preset = "veryfast";  ///< x264 preset
  int crf = 20;                     ///< x264 constant rate factor (0..51, lower = better)
  int threads = 2;                  ///< pinned encoder threads: the bytes depend on it
};

/// MP4 (libx264, yuv420p, +faststart, bitexact, no metadata) through an ffmpeg child process.
class FfmpegSink : public FrameSink {
 public:
  /// Starts `ffmpeg` writing `path` for frames of width x height at `fps` (even sizes: yuv420p).
  /// @throws RenderError naming the Debian package ffmpeg if the program is missing;
  /// std::invalid_argument on odd sizes or fps <= 0.
  FfmpegSink(const std::string& path, int width, int height, double fps,
             const FfmpegOptions& options = {});
  ~FfmpegSink() override;  ///< closes; errors are swallowed here, call Close() to see them
  void Write(const Image& frame) override;
  void Close() override;
  std::int64_t frames() const override { return frames_; }

 private:
  int width_, height_;
  int pipe_fd_ = -1;
  int pid_ = -1;
  std::int64_t frames_ = 0;
  std::string path_, log_path_;
};

/// Numbered PNG files dir/frame_000000.png, ... (directory created if absent).
class PngDirSink : public FrameSink {
 public:
  explicit PngDirSink(const std::string& dir);
  void Write(const Image& frame) override;
  void Close() override {}
  std::int64_t frames() const override { return frames_; }

 private:
  std::string dir_;
  std::int64_t frames_ = 0;
};

/// Full path of `program` found in PATH (or the program itself if it contains '/' and is
/// executable); empty if not found.
std::string FindProgram(const std::string& program);

}  // namespace arthrosim::render
