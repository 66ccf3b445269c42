// End to end on the real scene (Release builds only): every golden scene has a small golden file
// (the comparisons are the CTests Golden.<name>); `arthrosim score` on the tour passes its plan and
// fails the repair plan, gives byte-identical JSON twice, and exits 2 on a bad plan; the HTML
// report loads in headless Chromium without console errors and draws its plots and thumbnails.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "arthrosim/render/image.h"

namespace {

namespace fs = std::filesystem;

const std::string kBin = std::string(ARTHROSIM_BINARY_DIR) + "/src/cli/arthrosim";

std::string Dir() {
  static const std::string dir = [] {
    const fs::path d = fs::path(ARTHROSIM_BINARY_DIR) / "test_output" / "scoring_golden";
    fs::create_directories(d);
    return d.string();
  }();
  return dir;
}

int Shell(const std::string& command) {
  const int status = std::system((command + " >>" + Dir() + "/log.txt 2>&1").c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

std::string Slurp(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

// The tour run, made once by the fixture test Run.rotator_cuff_tour (tests/cli/CMakeLists.txt),
// which Golden.rotator_cuff_tour compares with its golden file.
const std::string& TourRun() {
  static const std::string path =
      std::string(ARTHROSIM_BINARY_DIR) + "/test_runs/rotator_cuff_tour.h5";
  EXPECT_TRUE(fs::exists(path)) << path << ": run by the CTest Run.rotator_cuff_tour";
  return path;
}

// Each scene's run is compared with its golden file by the CTest Golden.<name>; here, that every
// scene has a golden file and that each stays small enough to keep in git.
TEST(Golden, EverySceneHasASmallGoldenFile) {
  std::ifstream scenes("golden/scenes.txt");
  std::string line;
  int checked = 0;
  while (std::getline(scenes, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream f(line);
    std::string name;
    f >> name;
    const std::string golden = "golden/" + name + ".golden";
    ASSERT_TRUE(fs::exists(golden)) << golden << ": run tools/update-golden " << name;
    EXPECT_LT(fs::file_size(golden), 3u << 20) << golden;
    ++checked;
  }
  EXPECT_GE(checked, 1);
}

TEST(Golden, ScoreExitCodesAndDeterministicJson) {
  const std::string run = TourRun();
  const std::string d = Dir();
  EXPECT_EQ(
      Shell(kBin + " score " + run + " --plan scenarios/plans/rotator_cuff_tour.yaml --json " + d +
            "/a.json --xapi " + d + "/x.json --html " + d + "/report.html"),
      0);
  EXPECT_EQ(Shell(kBin + " score " + run +
                  " --plan scenarios/plans/rotator_cuff_tour.yaml --json " + d + "/b.json"),
            0);
  const std::string a = Slurp(d + "/a.json");
  EXPECT_FALSE(a.empty());
  EXPECT_EQ(a, Slurp(d + "/b.json"));
  EXPECT_NE(Slurp(d + "/x.json").find("\"verb\""), std::string::npos);
  // The repair plan's operations are not in the tour: it fails (exit 1).
  EXPECT_EQ(Shell(kBin + " score " + run + " --plan scenarios/plans/rotator_cuff_repair.yaml"), 1);
  std::ofstream(d + "/bad.yaml") << "name: bad\nsteps: []\n";
  EXPECT_EQ(Shell(kBin + " score " + run + " --plan " + d + "/bad.yaml"), 2);
  EXPECT_EQ(
      Shell(kBin + " score " + d + "/missing.h5 --plan scenarios/plans/rotator_cuff_tour.yaml"), 2);
  EXPECT_EQ(Shell(kBin + " compare " + run + " " + d + "/missing.h5"), 2);
  EXPECT_EQ(Shell(kBin + " compare " + run + " " + run + " --exact"), 0);
}

std::string Chromium() {
  for (const char* p : {"/usr/bin/chromium", "/usr/bin/chromium-browser"})
    if (fs::exists(p)) return p;
  return "";
}

TEST(Golden, HtmlReportRendersInHeadlessChromium) {
  const std::string chromium = Chromium();
  if (chromium.empty()) GTEST_SKIP() << "chromium is not installed (Debian package chromium)";
  const std::string d = Dir();
  const std::string html = d + "/chromium_report.html";
  ASSERT_EQ(Shell(kBin + " score " + TourRun() +
                  " --plan scenarios/plans/rotator_cuff_tour.yaml --html " + html),
            0);
  const std::string profile = d + "/chromium_profile";
  fs::remove_all(profile);
  const std::string png = d + "/report.png";
  fs::remove(png);
  const std::string log = d + "/chromium.log";
  const std::string cmd =
      chromium +
      " --headless --no-sandbox --disable-gpu --no-first-run --disable-background-networking"
      " --disable-component-update --disable-sync --user-data-dir=" +
      profile +
      " --enable-logging=stderr --v=0 --hide-scrollbars --window-size=1000,2400 --screenshot=" +
      png + " file://" + fs::absolute(html).string() + " >" + log + " 2>&1";
  ASSERT_EQ(std::system(cmd.c_str()), 0) << Slurp(log);
  const std::string messages = Slurp(log);
  EXPECT_EQ(messages.find("CONSOLE"), std::string::npos) << messages;
  EXPECT_EQ(messages.find("Uncaught"), std::string::npos) << messages;
  const arthrosim::render::Image image = arthrosim::render::ReadPng(png);
  ASSERT_GT(image.width, 0);
  // Plots: step bars (green #4caf50) and force/path polylines (#1f77b4); thumbnails: the black
  // surround of the scope's image circle (each ~20k pixels at 240 x 180).
  long green = 0, blue = 0, black = 0;
  for (int y = 0; y < image.height; ++y) {
    for (int x = 0; x < image.width; ++x) {
      const std::uint8_t* p = image.At(x, y);
      if (p[0] == 76 && p[1] == 175 && p[2] == 80) ++green;
      if (std::abs(p[0] - 31) < 20 && std::abs(p[1] - 119) < 20 && std::abs(p[2] - 180) < 20)
        ++blue;
      if (p[0] < 8 && p[1] < 8 && p[2] < 8) ++black;
    }
  }
  EXPECT_GT(green, 200) << "no step bars in the timeline";
  EXPECT_GT(blue, 100) << "no instrument curves";
  EXPECT_GT(black, 4 * 10000) << "thumbnails missing";
}

}  // namespace
