#pragma once
// Helpers shared by the tests that run the arthrosim binary: a scratch folder per test, and a
// live session (serve + the OpenIGTLink streaming client) waited for to its end.
#include <gtest/gtest.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <thread>

namespace arthrosim::testing {

/// A fixture with a fresh folder per test, $TMP/<prefix><test name>_<pid>, removed after the
/// test. The process id keeps two test runs (two build trees) on one machine out of each
/// other's way: one run's TearDown must not remove the folder the other is writing.
class TempDirTest : public ::testing::Test {
 protected:
  explicit TempDirTest(std::string prefix) : prefix_(std::move(prefix)) {}
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() /
           (prefix_ + ::testing::UnitTest::GetInstance()->current_test_info()->name() + "_" +
            std::to_string(getpid()));
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  /// The path of `name` in the test's folder.
  std::string P(const std::string& name) const { return (dir_ / name).string(); }

  std::filesystem::path dir_;

 private:
  std::string prefix_;
};

/// Starts `binary run scenario --steps steps --quiet --out out` as a child process; returns its
/// process id, or -1 if it could not fork.
inline pid_t SpawnRun(const std::string& binary, const std::string& scenario, const char* steps,
                      const std::string& out) {
  const pid_t pid = fork();
  if (pid == 0) {
    execl(binary.c_str(), binary.c_str(), "run", scenario.c_str(), "--steps", steps, "--quiet",
          "--out", out.c_str(), static_cast<char*>(nullptr));
    _exit(127);
  }
  return pid;
}

/// Runs the streaming client's command line `stream` until it succeeds (it fails while the
/// server, the child process `server`, does not listen yet: 40 tries 250 ms apart), then waits
/// for the server to end. Fails the test if the client never succeeds or the server does not
/// exit with status 0; call through ASSERT_NO_FATAL_FAILURE.
inline void StreamThenWaitForServer(const std::string& stream, pid_t server) {
  int rc = 1;
  for (int attempt = 0; attempt < 40 && rc != 0; ++attempt) {
    std::this_thread::sleep_for(std::chrono::milliseconds(250));
    rc = std::system(stream.c_str());
  }
  ASSERT_EQ(rc, 0) << stream;
  int status = 0;
  waitpid(server, &status, 0);
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << "serve status " << status;
}

}  // namespace arthrosim::testing
