// The bad-input corpus (tests/testdata/bad/cases.txt): every input the product reads, broken
// once each, must give its exit code and a message naming the file, line and field — never a
// crash, a hang or a partial output. One test per line of the manifest.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <ostream>
#include <string>
#include <vector>

namespace {

namespace fs = std::filesystem;

const std::string kBinary = std::string(ARTHROSIM_BINARY_DIR) + "/src/cli/arthrosim";
const std::string kBad = std::string(ARTHROSIM_SOURCE_DIR) + "/tests/testdata/bad";
const std::string kScenes = std::string(ARTHROSIM_SOURCE_DIR) + "/tests/testdata/scenes";

struct Case {
  std::string id;
  std::string args;
  int exit_code = 0;
  std::string expected;
};

// gtest prints a failing case by its id and arguments, not as bytes.
void PrintTo(const Case& c, std::ostream* os) { *os << c.id << ": arthrosim " << c.args; }

std::string Trim(const std::string& s) {
  const auto a = s.find_first_not_of(" \t");
  const auto b = s.find_last_not_of(" \t");
  return a == std::string::npos ? "" : s.substr(a, b - a + 1);
}

// Reads cases.txt: "id | args | exit | expected" lines; '#' starts a comment line.
std::vector<Case> LoadCases() {
  std::vector<Case> cases;
  std::ifstream in(kBad + "/cases.txt");
  std::string line;
  while (std::getline(in, line)) {
    if (Trim(line).empty() || Trim(line)[0] == '#') continue;
    std::vector<std::string> parts;
    std::size_t start = 0;
    for (int k = 0; k < 3; ++k) {
      const std::size_t bar = line.find(" | ", start);
      if (bar == std::string::npos) break;
      parts.push_back(Trim(line.substr(start, bar - start)));
      start = bar + 3;
    }
    parts.push_back(Trim(line.substr(start)));
    if (parts.size() != 4) {
      cases.push_back({"malformed_manifest_line", line, -1, ""});
      continue;
    }
    cases.push_back({parts[0], parts[1], std::atoi(parts[2].c_str()), parts[3]});
  }
  return cases;
}

// The files the cases share, made once: a valid run, an HDF5 file that is not a run, the first
// half of the valid run, and a text file named .h5.
class BadInput : public ::testing::TestWithParam<Case> {
 protected:
  static void SetUpTestSuite() {
    root_ = fs::temp_directory_path() / ("arthrosim_bad_input_" + std::to_string(getpid()));
    fs::remove_all(root_);
    fs::create_directories(root_);
    run_ = (root_ / "run.h5").string();
    const std::string make_run = kBinary + " run " + kScenes + "/small.yaml --trajectory " +
                                 kScenes + "/small_session.csv --quiet --out " + run_ +
                                 " > /dev/null 2>&1";
    ASSERT_EQ(std::system(make_run.c_str()), 0) << make_run;
    notrun_ = (root_ / "notrun.h5").string();
    const std::string make_notrun = "/usr/bin/python3 -c \"import h5py; h5py.File('" + notrun_ +
                                    "', 'w').create_dataset('x', data=[1, 2, 3])\"";
    ASSERT_EQ(std::system(make_notrun.c_str()), 0) << make_notrun;
    truncated_ = (root_ / "truncated_run.h5").string();
    std::ifstream in(run_, std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    std::ofstream(truncated_, std::ios::binary) << bytes.substr(0, bytes.size() / 2);
    text_h5_ = (root_ / "text_named_h5.h5").string();
    std::ofstream(text_h5_) << "a text file named like an HDF5 session or run file\n";
    // The valid run without its checkpoints, and as if written by another compiler.
    nockpt_ = (root_ / "no_checkpoints.h5").string();
    otherbuild_ = (root_ / "other_build.h5").string();
    fs::copy_file(run_, nockpt_);
    fs::copy_file(run_, otherbuild_);
    const std::string edit = "/usr/bin/python3 -c \"import h5py; del h5py.File('" + nockpt_ +
                             "', 'a')['checkpoints']; h5py.File('" + otherbuild_ +
                             "', 'a')['meta'].attrs['compiler'] = 'OtherCC 1.0'\"";
    ASSERT_EQ(std::system(edit.c_str()), 0) << edit;
    fifo_ = (root_ / "fifo.stl").string();
    ASSERT_EQ(mkfifo(fifo_.c_str(), 0600), 0) << fifo_;
    // The bad HDF5 sessions ({made}/session_*.h5), written here rather than kept as binaries.
    const std::string make_sessions = "/usr/bin/python3 " + std::string(ARTHROSIM_SOURCE_DIR) +
                                      "/tests/cli/make_bad_sessions.py " + root_.string();
    ASSERT_EQ(std::system(make_sessions.c_str()), 0) << make_sessions;
  }
  static void TearDownTestSuite() { fs::remove_all(root_); }

  static std::string Expand(std::string s, const std::string& out) {
    const std::array<std::pair<const char*, std::string>, 11> subs = {
        {{"{nockpt_run}", nockpt_},
         {"{made}", root_.string()},
         {"{fifo}", fifo_},
         {"{otherbuild_run}", otherbuild_},
         {"{bad}", kBad},
         {"{scenes}", kScenes},
         {"{out}", out},
         {"{run}", run_},
         {"{notrun}", notrun_},
         {"{truncated_run}", truncated_},
         {"{text_h5}", text_h5_}}};
    for (const auto& [key, value] : subs) {
      for (std::size_t at = s.find(key); at != std::string::npos; at = s.find(key, at)) {
        s.replace(at, std::string(key).size(), value);
        at += value.size();
      }
    }
    return s;
  }

  static fs::path root_;
  static std::string run_, notrun_, truncated_, text_h5_, nockpt_, otherbuild_, fifo_;
};

fs::path BadInput::root_;
std::string BadInput::run_, BadInput::notrun_, BadInput::truncated_, BadInput::text_h5_,
    BadInput::nockpt_, BadInput::otherbuild_, BadInput::fifo_;

TEST_P(BadInput, ExitsWithItsCodeAndNamesTheFault) {
  const Case& c = GetParam();
  ASSERT_NE(c.id, "malformed_manifest_line") << "cases.txt line: " << c.args;
  const fs::path out = root_ / ("out_" + c.id);
  fs::create_directories(out);
  const std::string cmd = kBinary + " " + Expand(c.args, out.string()) + " 2>&1";
  std::string output;
  FILE* pipe = popen(cmd.c_str(), "r");
  ASSERT_NE(pipe, nullptr);
  std::array<char, 4096> buf{};
  while (std::fgets(buf.data(), buf.size(), pipe)) output += buf.data();
  const int status = pclose(pipe);
  ASSERT_TRUE(WIFEXITED(status)) << "crashed: " << cmd << "\n" << output;
  EXPECT_EQ(WEXITSTATUS(status), c.exit_code) << cmd << "\n" << output;
  EXPECT_NE(output.find(Expand(c.expected, out.string())), std::string::npos)
      << cmd << "\nexpected to contain: " << Expand(c.expected, out.string())
      << "\ngot: " << output;
  if (c.exit_code == 2) {
    EXPECT_TRUE(fs::is_empty(out)) << "a refused command left output behind in " << out;
  }
}

INSTANTIATE_TEST_SUITE_P(Corpus, BadInput, ::testing::ValuesIn(LoadCases()),
                         [](const ::testing::TestParamInfo<Case>& info) { return info.param.id; });

}  // namespace
