#include "arthrosim/render/video_sink.h"

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <vector>

extern char** environ;

namespace arthrosim::render {
namespace {

std::string ReadTail(const std::string& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  std::string s = ss.str();
  if (s.size() > 2000) s = s.substr(s.size() - 2000);
  return s;
}

// write() of the whole buffer; SIGPIPE is blocked for this thread while writing so a dead
// encoder surfaces as EPIPE instead of killing the process.
bool WriteAll(int fd, const std::uint8_t* data, std::size_t n) {
  sigset_t block, old;
  sigemptyset(&block);
  sigaddset(&block, SIGPIPE);
  pthread_sigmask(SIG_BLOCK, &block, &old);
  bool ok = true;
  while (n > 0) {
    const ssize_t k = ::write(fd, data, n);
    if (k < 0) {
      if (errno == EINTR) continue;
      ok = false;
      break;
    }
    data += k;
    n -= static_cast<std::size_t>(k);
  }
  if (!ok && errno == EPIPE) {
    // consume the pending SIGPIPE before unblocking
    const timespec zero{0, 0};
    sigtimedwait(&block, nullptr, &zero);
  }
  pthread_sigmask(SIG_SETMASK, &old, nullptr);
  return ok;
}

}  // namespace

std::string FindProgram(const std::string& program) {
  if (program.find('/') != std::string::npos) {
    return ::access(program.c_str(), X_OK) == 0 ? program : std::string();
  }
  const char* path = std::getenv("PATH");
  std::stringstream dirs(path != nullptr ? path : "/usr/bin:/bin");
  std::string dir;
  while (std::getline(dirs, dir, ':')) {
    if (dir.empty()) dir.assign(1, '.');  // not = ".": GCC 12 -Wrestrict false positive
    std::string full = dir;               // appended: GCC 12 -Wrestrict false positive on operator+
    full += '/';
    full += program;
    struct stat st {};
    if (::stat(full.c_str(), &st) == 0 && S_ISREG(st.st_mode) &&
        ::access(full.c_str(), X_OK) == 0) {
      return full;
    }
  }
  return {};
}

FfmpegSink::FfmpegSink(const std::string& path, int width, int height, double fps,
                       const FfmpegOptions& options)
    : width_(width), height_(height), path_(path) {
  if (width <= 0 || height <= 0 || width % 2 != 0 || height % 2 != 0) {
    throw std::invalid_argument("video size " + std::to_string(width) + "x" +
                                std::to_string(height) +
                                ": expected positive even sizes (yuv420p)");
  }
  if (!(fps > 0) || fps > 1000) throw std::invalid_argument("video fps: expected 0 < fps <= 1000");
  if (options.threads < 1) throw std::invalid_argument("ffmpeg threads: expected >= 1");
  const std::filesystem::path parent = std::filesystem::path(path).parent_path();
  if (!parent.empty() && !std::filesystem::is_directory(parent)) {
    throw RenderError("video output '" + path + "': directory '" + parent.string() +
                      "' does not exist");
  }
  const std::string exe = FindProgram(options.program);
  if (exe.empty()) {
    throw RenderError("video output needs the program '" + options.program +
                      "', which was not found in PATH: install the Debian package ffmpeg "
                      "(apt-get install ffmpeg), or write PNG frames instead (--frames-dir)");
  }
  char rate[64];
  std::snprintf(rate, sizeof rate, "%.17g", fps);
  const std::string size = std::to_string(width) + "x" + std::to_string(height);
  const std::string threads = std::to_string(options.threads);
  const std::vector<std::string> args = {exe,
                                         "-nostdin",
                                         "-hide_banner",
                                         "-loglevel",
                                         "error",
                                         "-y",
                                         "-f",
                                         "rawvideo",
                                         "-pix_fmt",
                                         "rgb24",
                                         "-s",
                                         size,
                                         "-framerate",
                                         rate,
                                         "-i",
                                         "pipe:0",
                                         "-an",
                                         "-c:v",
                                         "libx264",
                                         "-preset",
                                         options.preset,
                                         "-crf",
                                         std::to_string(options.crf),
                                         "-pix_fmt",
                                         "yuv420p",
                                         "-threads",
                                         threads,
                                         "-movflags",
                                         "+faststart",
                                         "-fflags",
                                         "+bitexact",
                                         "-flags:v",
                                         "+bitexact",
                                         "-map_metadata",
                                         "-1",
                                         path};
  std::vector<char*> argv;
  for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);

  // stdin from our pipe, stderr to a log file next to the output (removed on success)
  int fds[2];
  if (::pipe2(fds, O_CLOEXEC) != 0)
    throw RenderError("pipe() failed: " + std::string(std::strerror(errno)));
  log_path_ = path + ".ffmpeg.log";
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_adddup2(&actions, fds[0], 0);
  posix_spawn_file_actions_addopen(&actions, 2, log_path_.c_str(), O_WRONLY | O_CREAT | O_TRUNC,
                                   0644);
  posix_spawn_file_actions_addopen(&actions, 1, "/dev/null", O_WRONLY, 0);
  pid_t pid = -1;
  const int rc = posix_spawn(&pid, exe.c_str(), &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  ::close(fds[0]);
  if (rc != 0) {
    ::close(fds[1]);
    throw RenderError("cannot start '" + exe + "': " + std::strerror(rc));
  }
  pid_ = pid;
  pipe_fd_ = fds[1];
}

FfmpegSink::~FfmpegSink() {
  try {
    Close();
  } catch (...) {
    // destructors must not throw; Close() reports errors to callers that want them
  }
}

void FfmpegSink::Write(const Image& frame) {
  if (pipe_fd_ < 0) throw RenderError("FfmpegSink::Write after Close");
  if (frame.width != width_ || frame.height != height_) {
    throw RenderError("video frame " + std::to_string(frame.width) + "x" +
                      std::to_string(frame.height) + " differs from the video size " +
                      std::to_string(width_) + "x" + std::to_string(height_));
  }
  if (!WriteAll(pipe_fd_, frame.rgb.data(), frame.rgb.size())) {
    const std::string err = std::strerror(errno);
    Close();  // throws with ffmpeg's own message if it exited with an error
    throw RenderError("writing to ffmpeg failed: " + err);
  }
  ++frames_;
}

void FfmpegSink::Close() {
  if (pid_ < 0) return;
  if (pipe_fd_ >= 0) ::close(pipe_fd_);
  pipe_fd_ = -1;
  int status = 0;
  while (::waitpid(pid_, &status, 0) < 0 && errno == EINTR) {
  }
  pid_ = -1;
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    throw RenderError("ffmpeg failed writing '" + path_ + "' (log " + log_path_ + "):\n" +
                      ReadTail(log_path_));
  }
  std::error_code ec;
  std::filesystem::remove(log_path_, ec);
}

PngDirSink::PngDirSink(const std::string& dir) : dir_(dir) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec || !std::filesystem::is_directory(dir)) {
    throw RenderError("cannot create frames directory '" + dir + "': " + ec.message());
  }
}

void PngDirSink::Write(const Image& frame) {
  char name[32];
  std::snprintf(name, sizeof name, "frame_%06lld.png", static_cast<long long>(frames_));
  WritePng((std::filesystem::path(dir_) / name).string(), frame);
  ++frames_;
}

}  // namespace arthrosim::render
