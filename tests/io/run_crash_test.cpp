// A writer killed with SIGKILL mid-run leaves a file that h5py (swmr=True) and RunReader read
// up to at least the last flush, every readable frame intact. Also: a live file is readable.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>

#include "arthrosim/io/run_reader.h"
#include "arthrosim/io/run_writer.h"
#include "run_fixture.h"

namespace arthrosim::io {
namespace {

using testing::MakeFrame;
using testing::MakeModel;

// Child: writes frames forever (until killed), reporting each flush's frame count on `fd`.
[[noreturn]] void WriteUntilKilled(const std::string& path, int fd) {
  try {
    const Model model = MakeModel();
    RunWriter w(path, model, MakeFrame(model, 0));
    std::int64_t reported = w.flushed_frames();
    ::write(fd, &reported, sizeof reported);
    for (int f = 1; f < 100000; ++f) {
      w.Append(MakeFrame(model, f));  // flushes every 5 frames (0.1 s at 0.02 s per frame)
      if (w.flushed_frames() != reported) {
        reported = w.flushed_frames();
        if (::write(fd, &reported, sizeof reported) != sizeof reported) ::_exit(4);
      }
    }
  } catch (...) {
    ::_exit(3);
  }
  ::_exit(2);  // should have been killed long before
}

TEST(RunCrash, SigkillLeavesAReadableFileUpToTheLastFlush) {
  const std::string path = testing::TestDir("crash") + "/run.h5";
  int fds[2];
  ASSERT_EQ(::pipe(fds), 0);
  const pid_t pid = ::fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    ::close(fds[0]);
    WriteUntilKilled(path, fds[1]);
  }
  ::close(fds[1]);
  // Wait for the 4th flush report (1, 5, 10, 15 frames flushed), then kill while it writes on.
  std::int64_t flushed = 0;
  for (int reports = 0; reports < 4; ++reports) {
    ASSERT_EQ(::read(fds[0], &flushed, sizeof flushed), static_cast<ssize_t>(sizeof flushed))
        << "writer child died early";
  }
  ::kill(pid, SIGKILL);
  int status = 0;
  ::waitpid(pid, &status, 0);
  ::close(fds[0]);
  ASSERT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL) << "child status " << status;
  ASSERT_GE(flushed, 15);

  const RunReader r(path);
  EXPECT_GE(r.frame_count(), flushed);
  const Model model = MakeModel();
  State got;
  for (std::int64_t k = 0; k < r.frame_count(); ++k) {
    r.ReadFrame(k, got);
    EXPECT_TRUE(testing::EqualWithinPositionBound(got, MakeFrame(model, static_cast<int>(k))))
        << "frame " << k;
  }
  std::printf("killed writer: %lld frames flushed, %lld readable\n",
              static_cast<long long>(flushed), static_cast<long long>(r.frame_count()));

  ASSERT_TRUE(testing::HavePythonH5py()) << "python3-h5py is required by the io tests";
  EXPECT_EQ(testing::RunPython("check_run.py", path + " --min-frames " + std::to_string(flushed)),
            0);
}

// HDF5 will not open one file for SWMR write and SWMR read in the same process: the writer is a
// child, synchronised with the reader through two pipes.
TEST(RunCrash, ReaderFollowsALiveWriter) {
  const std::string path = testing::TestDir("live") + "/run.h5";
  int up[2], down[2];  // child -> parent, parent -> child
  ASSERT_EQ(::pipe(up), 0);
  ASSERT_EQ(::pipe(down), 0);
  const pid_t pid = ::fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    char c = 0;
    try {
      const Model model = MakeModel();
      RunWriter w(path, model, MakeFrame(model, 0));
      for (int f = 1; f <= 7; ++f) w.Append(MakeFrame(model, f));
      w.Flush();
      if (::write(up[1], "1", 1) != 1 || ::read(down[0], &c, 1) != 1) ::_exit(4);
      w.Append(MakeFrame(model, 8));
      w.Flush();
      if (::write(up[1], "2", 1) != 1 || ::read(down[0], &c, 1) != 1) ::_exit(4);
      w.Close();
    } catch (...) {
      ::_exit(3);
    }
    ::_exit(0);
  }
  char c = 0;
  ASSERT_EQ(::read(up[0], &c, 1), 1);
  const Model model = MakeModel();
  RunReader r(path);  // the writer still has it open
  EXPECT_EQ(r.frame_count(), 8);
  EXPECT_TRUE(testing::EqualWithinPositionBound(r.Frame(7),
                                                MakeFrame(model, 7)));  // after splits and growth
  ASSERT_EQ(::write(down[1], "g", 1), 1);
  ASSERT_EQ(::read(up[0], &c, 1), 1);
  EXPECT_EQ(r.Refresh(), 9);
  EXPECT_TRUE(testing::EqualWithinPositionBound(r.Frame(8), MakeFrame(model, 8)));
  ASSERT_EQ(::write(down[1], "g", 1), 1);
  int status = 0;
  ::waitpid(pid, &status, 0);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << "writer status " << status;
  for (int fd : {up[0], up[1], down[0], down[1]}) ::close(fd);
}

}  // namespace
}  // namespace arthrosim::io
