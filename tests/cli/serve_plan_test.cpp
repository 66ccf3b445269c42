// Live feedback end to end on the shoulder scene. The novice damage variant
// (trajectories/rotator_cuff_repair_novice_damage.yaml) is run with `run --plan` and recorded;
// the recording is streamed through `serve --plan` by the OpenIGTLink client. In both run files
// the warnings (live_warning events; at the client, STRING notices) sit where offline scoring of
// that same file flags the session: order violations, force over the limit, damage on the
// protected muscle (debounced), contact, contact time and volume outside the targets; and
// replaying the file through the live evaluator gives the warnings it holds.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "arthrosim/scoring/live.h"
#include "arthrosim/scoring/plan.h"
#include "arthrosim/scoring/run_data.h"
#include "arthrosim/scoring/score.h"
#include "cli_test_util.h"

namespace arthrosim::scoring {
namespace {

namespace fs = std::filesystem;

const std::string kBinary = std::string(ARTHROSIM_BINARY_DIR) + "/src/cli/arthrosim";
const std::string kClient = std::string(ARTHROSIM_BINARY_DIR) + "/src/input/igtl_stream_client";
const std::string kSource = ARTHROSIM_SOURCE_DIR;
const std::string kScenario = kSource + "/scenarios/rotator_cuff_repair.yaml";
const std::string kPlan = kSource + "/scenarios/plans/rotator_cuff_repair.yaml";
const std::string kNovice = kSource + "/trajectories/rotator_cuff_repair_novice_damage.yaml";

struct Warning {
  std::string type, subject;
  double time_s = 0;
};

std::string Field(const std::string& detail, const std::string& key) {
  std::istringstream in(detail);
  std::string token;
  while (in >> token)
    if (token.rfind(key + "=", 0) == 0) return token.substr(key.size() + 1);
  return "";
}

std::vector<Warning> WarningEvents(const RunData& run) {
  std::vector<Warning> out;
  for (const Event& e : run.events)
    if (e.kind == kWarningEventKind)
      out.push_back({Field(e.detail, "type"), Field(e.detail, "subject"), e.time_s});
  return out;
}

std::vector<double> TimesOf(const std::vector<Warning>& all, const std::string& type) {
  std::vector<double> t;
  for (const Warning& w : all)
    if (w.type == type) t.push_back(w.time_s);
  return t;
}

bool HasAt(const std::vector<Warning>& all, const std::string& type, const std::string& subject,
           double t_s) {
  for (const Warning& w : all)
    if (w.type == type && (subject.empty() || w.subject == subject) &&
        std::abs(w.time_s - t_s) < 1e-6)
      return true;
  return false;
}

const Metric& Find(const ScoreReport& r, const std::string& id) {
  for (const Metric& m : r.metrics)
    if (m.id == id) return m;
  throw std::runtime_error("no metric " + id);
}

// The run file's warnings against offline scoring of the same file. Returns the warning types.
std::set<std::string> ExpectWarningsWhereScoringFlags(const std::string& path) {
  const Model model = LoadRunModel(path, kScenario);
  const Plan plan = LoadPlan(kPlan, &model);
  const RunData run = ReadRunData(path, model);
  const ScoreReport report = Evaluate(plan, run);
  const std::vector<Warning> warnings = WarningEvents(run);
  std::set<std::string> types;
  for (const Warning& w : warnings) types.insert(w.type);

  // order and force: a warning at the time of each offline violation
  std::vector<double> damage_s;
  for (const Violation& v : report.violations) {
    if (v.kind == "order") {
      EXPECT_TRUE(HasAt(warnings, "order", v.step, v.time_s)) << v.text;
    } else if (v.kind == "force") {
      EXPECT_TRUE(HasAt(warnings, "force", "muscle_belly", v.time_s)) << v.text;
    } else if (v.kind == "damage") {
      damage_s.push_back(v.time_s);
    }
  }
  for (const Warning& w : warnings) {
    if (w.type != "order") continue;
    bool flagged = false;
    for (const Violation& v : report.violations) flagged = flagged || v.step == w.subject;
    EXPECT_TRUE(flagged) << "order warning for " << w.subject << " that scoring does not flag";
  }
  // damage: scoring flags each episode (events less than the quiet time apart) once, at its
  // first event; live warns at the same times (the debounce: no damage during the quiet time)
  const std::vector<double> got = TimesOf(warnings, "damage");
  EXPECT_EQ(got.size(), damage_s.size());
  for (std::size_t i = 0; i < got.size() && i < damage_s.size(); ++i)
    EXPECT_NEAR(got[i], damage_s[i], 1e-9);
  EXPECT_LT(damage_s.size(),
            static_cast<std::size_t>(Find(report, "safety.muscle_belly.damage_events").value))
      << "a shaver pass is one episode, not one violation per event";
  // metrics without a time: a warning exactly when scoring fails or counts them
  EXPECT_EQ(types.count("contact_time") > 0,
            !Find(report, "safety.muscle_belly.contact_time").pass);
  EXPECT_EQ(types.count("force") > 0, !Find(report, "safety.muscle_belly.time_over_force").pass);
  EXPECT_EQ(types.count("contact") > 0, Find(report, "safety.muscle_belly.contact_time").value > 0);
  EXPECT_EQ(types.count("outside_target") > 0, !Find(report, "safety.volume_outside_target").pass);
  // the live evaluator replayed frame by frame over the file gives the warnings it holds
  const std::vector<LiveWarning> replay = ReplayLive(plan, model, path);
  EXPECT_EQ(replay.size(), warnings.size());
  for (std::size_t i = 0; i < replay.size() && i < warnings.size(); ++i) {
    EXPECT_EQ(replay[i].type, warnings[i].type);
    EXPECT_EQ(replay[i].subject, warnings[i].subject);
    EXPECT_EQ(replay[i].time_s, warnings[i].time_s);
  }
  std::printf(
      "%s: %zu warnings; %zu damage events; outside targets %.2f mm3; muscle peak %.2f N, "
      "contact %.2f s\n",
      fs::path(path).filename().c_str(), warnings.size(), damage_s.size(),
      Find(report, "safety.volume_outside_target").value,
      Find(report, "safety.muscle_belly.peak_force").value,
      Find(report, "safety.muscle_belly.contact_time").value);
  return types;
}

std::vector<Warning> ReadNotices(const std::string& path) {
  std::vector<Warning> out;
  std::ifstream in(path);
  std::string line;
  while (std::getline(in, line)) {  // t <TAB> device <TAB> "WARNING type subject t=..: ..."
    std::istringstream f(line);
    Warning w;
    std::string device, tag;
    f >> w.time_s >> device >> tag >> w.type >> w.subject;
    EXPECT_EQ(device, "Warning") << line;
    EXPECT_EQ(tag, "WARNING") << line;
    out.push_back(w);
  }
  return out;
}

TEST(ServePlan, WarningsArriveWhereOfflineScoringFlagsTheSession) {
  if (!fs::exists(kClient)) GTEST_SKIP() << "built without OpenIGTLink";
  const fs::path dir =
      fs::temp_directory_path() / ("arthrosim_serve_plan_" + std::to_string(getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::string offline = (dir / "offline.h5").string(), rec = (dir / "novice.csv").string();
  const std::string live = (dir / "live.h5").string(), notices = (dir / "notices.txt").string();

  // 1. The scripted novice with live feedback, recorded.
  const std::string run = kBinary + " run " + kScenario + " --trajectory " + kNovice + " --plan " +
                          kPlan + " --record " + rec + " --out " + offline + " --quiet";
  ASSERT_EQ(std::system(run.c_str()), 0) << run;
  const std::set<std::string> scripted = ExpectWarningsWhereScoringFlags(offline);
  for (const char* type : {"contact", "contact_time", "force", "damage", "order", "outside_target"})
    EXPECT_EQ(scripted.count(type), 1u) << "the novice variant gives no " << type << " warning";

  // 2. The recording streamed live through serve --plan (the client keeps reading until the
  //    server closes: --duration covers the session and a late connection).
  const std::string port = std::to_string(20000 + (getpid() + 7919) % 20000);
  const pid_t pid = fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    execl(kBinary.c_str(), kBinary.c_str(), "serve", kScenario.c_str(), "--plan", kPlan.c_str(),
          "--port", port.c_str(), "--duration", "12", "--out", live.c_str(), "--quiet",
          static_cast<char*>(nullptr));
    _exit(127);
  }
  const std::string stream = kClient + " " + rec + " --port " + port +
                             " --no-end --linger 60 --notices " + notices + " > " +
                             (dir / "client.log").string() + " 2>&1";
  ASSERT_NO_FATAL_FAILURE(arthrosim::testing::StreamThenWaitForServer(stream, pid));

  const std::set<std::string> served = ExpectWarningsWhereScoringFlags(live);
  // Paced to the wall clock, the live run samples the recording at its own times; these
  // conditions last long enough to appear whatever the machine's load.
  for (const char* type : {"contact", "damage", "order", "outside_target"})
    EXPECT_EQ(served.count(type), 1u) << "the live session gives no " << type << " warning";
  // every warning of the run file reached the client as a STRING, in order, at its time
  const RunData data = ReadRunData(live, LoadRunModel(live, kScenario));
  const std::vector<Warning> recorded = WarningEvents(data);
  const std::vector<Warning> received = ReadNotices(notices);
  ASSERT_EQ(received.size(), recorded.size());
  for (std::size_t i = 0; i < received.size(); ++i) {
    EXPECT_EQ(received[i].type, recorded[i].type) << i;
    EXPECT_EQ(received[i].subject, recorded[i].subject) << i;
    EXPECT_NEAR(received[i].time_s, recorded[i].time_s, 1e-6) << i;
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace arthrosim::scoring
