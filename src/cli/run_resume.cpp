#include "run_resume.h"

#include <fmt/core.h>
#include <signal.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "arthrosim/core/error.h"
#include "arthrosim/core/hash.h"
#include "arthrosim/core/input_file.h"
#include "arthrosim/io/run_checkpoint.h"
#include "arthrosim/io/run_reader.h"
#include "arthrosim/io/scenario_loader.h"

namespace arthrosim::cli {
namespace {

namespace fs = std::filesystem;

bool IsLive(const std::string& spec) { return spec == "igtl" || spec.rfind("igtl:", 0) == 0; }

bool IsFileSpec(const std::string& spec) { return spec != "none" && !IsLive(spec); }

std::string ReadText(const std::string& path) {
  return ReadInputFile(path, "scenario", "cannot open the scenario file");
}

/// The new run file's record of its input (file specs made absolute, so that --resume works
/// from another directory).
io::RunOrigin InputOrigin(const RunStart& s) {
  io::RunOrigin o;
  o.trajectory = s.trajectory;
  if (IsFileSpec(s.trajectory)) {
    std::error_code ec;
    const fs::path abs = fs::absolute(s.trajectory, ec);
    if (!ec) o.trajectory = abs.lexically_normal().string();
    o.trajectory_sha256 = FileSha256(s.trajectory);
  }
  o.noise_seed = s.seed ? static_cast<std::int64_t>(*s.seed) : -1;
  o.noise_scale = s.noise_scale;
  return o;
}

RunStart FreshStart(const RunRequest& r) {
  if (r.scenario.empty()) {
    throw InputError("", 0, "scenario",
                     "run needs a SCENARIO file (or --resume RUN.h5, or --from RUN.h5 --at T)");
  }
  RunStart s;
  s.model = io::LoadScenario(r.scenario);
  s.state = MakeInitialState(s.model);
  s.trajectory = r.trajectory.empty() ? "none" : r.trajectory;
  s.seed = r.seed;
  s.noise_scale = r.noise_scale.value_or(0.0);
  s.origin = InputOrigin(s);
  return s;
}

/// The Model of the run file's scenario; a SCENARIO given on the command line must be it.
Model ModelOf(const io::RunCheckpoints& cp, const std::string& scenario) {
  if (!scenario.empty()) {
    const std::string sha = Sha256Hex(ReadText(scenario));
    if (sha != cp.scenario_sha256()) {
      throw InputError(scenario, 0, "scenario",
                       fmt::format("is not the scenario of {} (SHA-256 {}, the run's {} was {}); "
                                   "leave SCENARIO out to use the run's own",
                                   cp.path(), sha.substr(0, 12), cp.scenario_path(),
                                   cp.scenario_sha256().substr(0, 12)));
    }
  }
  // The exact text stored in the run; its meshes are read relative to its recorded path.
  Model model = io::LoadScenarioFromText(
      cp.scenario_yaml(),
      io::LocateRunScenario(cp.path(), cp.scenario_path(), cp.scenario_path_absolute()));
  if (model.scenario_sha256 != cp.scenario_sha256()) {
    throw InputError(cp.path(), 0, "meta/scenario_yaml",
                     "the stored scenario text does not match its recorded SHA-256: damaged file");
  }
  return model;
}

/// Simulated time of the run file's last complete frame, s.
double LastFrameTime(const std::string& path) {
  const io::RunReader reader(path);
  return reader.frame_count() > 0 ? reader.time(reader.frame_count() - 1) : 0.0;
}

std::size_t PickCheckpoint(const RunRequest& r, const io::RunCheckpoints& cp) {
  const auto& e = cp.entries();
  if (!r.resume.empty()) return e.size() - 1;
  const double t = *r.at_s;
  const double end = std::max(e.back().time_s, LastFrameTime(cp.path()));
  if (!(t >= 0) || t > end + 1e-3 * cp.dt_s()) {
    throw InputError(cp.path(), 0, "--at",
                     fmt::format("T = {} s is outside the run: it holds {} s to {} s", t,
                                 e.front().time_s, end));
  }
  const std::int64_t i = cp.AtOrBefore(t);
  if (i < 0) {
    throw InputError(cp.path(), 0, "--at",
                     fmt::format("no checkpoint at or before T = {} s: the first is at {} s", t,
                                 e.front().time_s));
  }
  return static_cast<std::size_t>(i);
}

/// The input of the parent run, reopened: it must be the same file as then.
void TakeParentInput(const io::RunCheckpoints& cp, RunStart* s) {
  const io::RunOrigin& p = cp.origin();
  if (IsLive(p.trajectory)) {
    throw InputError(cp.path(), 0, "meta/trajectory",
                     "the run was driven live (" + p.trajectory +
                         "): its input cannot be replayed; start from it with --from " + cp.path() +
                         " --at T --trajectory FILE");
  }
  if (!p.trajectory_sha256.empty() && FileSha256(p.trajectory) != p.trajectory_sha256) {
    throw InputError(p.trajectory, 0, "trajectory",
                     fmt::format("is missing or changed since {} was written (expected SHA-256 "
                                 "{}); the run's input must be the same to continue it",
                                 cp.path(), p.trajectory_sha256.substr(0, 12)));
  }
  s->trajectory = p.trajectory;
  s->seed = p.noise_seed >= 0 ? std::optional<std::uint64_t>(p.noise_seed) : std::nullopt;
  s->noise_scale = p.noise_scale;
  s->end_step = p.end_step;
}

RunStart CheckpointStart(const RunRequest& r) {
  const bool resume = !r.resume.empty();
  const std::string& path = resume ? r.resume : r.from;
  if (!resume && !r.at_s) {
    throw InputError(path, 0, "--at", "--from RUN.h5 needs --at T (simulated seconds)");
  }
  if (resume && (!r.trajectory.empty() || r.seed || r.noise_scale)) {
    throw InputError(path, 0, "--resume",
                     "continues the run with its own input; --trajectory, --seed and "
                     "--noise-scale go with --from RUN.h5 --at T");
  }
  const io::RunCheckpoints cp(path);
  if (cp.entries().empty()) {
    throw InputError(path, 0, "checkpoints",
                     "the file holds no checkpoint (written without checkpoints, by an older "
                     "build, or killed before its first); expected a run file written by "
                     "`arthrosim run`");
  }
  const std::string other = cp.BuildMismatch();
  if (!other.empty()) {
    throw InputError(path, 0, "meta",
                     "written by another build: " + other +
                         "; continue it with the build that wrote it (results are bit-identical "
                         "only within one build)");
  }
  RunStart s;
  s.model = ModelOf(cp, r.scenario);
  const std::size_t index = PickCheckpoint(r, cp);
  const io::CheckpointEntry& e = cp.entries()[index];
  s.state = cp.Read(index, s.model);
  s.restored = true;
  if (resume || r.trajectory.empty()) {
    TakeParentInput(cp, &s);
  } else {
    s.trajectory = r.trajectory;
  }
  if (r.seed) s.seed = r.seed;
  if (r.noise_scale) s.noise_scale = *r.noise_scale;
  s.origin = InputOrigin(s);
  std::error_code ec;
  const fs::path abs = fs::absolute(path, ec);
  s.origin.parent = ec ? path : abs.lexically_normal().string();
  s.origin.parent_step = e.step;
  s.origin.parent_time_s = e.time_s;
  s.origin.parent_state_hash = e.state_hash;
  const fs::path p(path);
  const std::string stem = (p.parent_path() / p.stem()).string();
  s.default_out = resume ? stem + ".resumed.h5" : fmt::format("{}.from_{:.6g}s.h5", stem, e.time_s);
  return s;
}

}  // namespace

RunStart PrepareRunStart(const RunRequest& request) {
  if (request.resume.empty() && request.from.empty()) return FreshStart(request);
  return CheckpointStart(request);
}

void CheckContinuation(const RunStart& start, const std::string& out, std::int64_t steps) {
  if (!start.restored) return;
  const std::string& parent = start.origin.parent;
  if (steps <= 0) {
    throw InputError(parent, 0, "--resume",
                     fmt::format("the run ended at step {} ({} s), its last checkpoint: nothing "
                                 "left to run; add --steps N or --duration S to run on",
                                 start.state.step, start.state.time_s));
  }
  std::error_code ec;
  if (fs::exists(out, ec) && fs::equivalent(out, parent, ec)) {
    throw InputError(out, 0, "--out",
                     "is the run file being continued; write the continuation to another file");
  }
}

std::string FileSha256(const std::string& path) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) return "";
  std::ifstream in(path, std::ios::binary);
  if (!in) return "";
  std::ostringstream ss;
  ss << in.rdbuf();
  return Sha256Hex(ss.str());
}

void InjectKillAfterStep(std::int64_t step) {
  static const std::int64_t kill_at = [] {
    const char* v = std::getenv("ARTHROSIM_FAULT_KILL_AT_STEP");
    return v != nullptr && *v != '\0' ? std::atoll(v) : std::int64_t{-1};
  }();
  if (kill_at < 0 || step != kill_at) return;
  const char* name = std::getenv("ARTHROSIM_FAULT_SIGNAL");
  const std::string sig = name != nullptr ? name : "KILL";
  raise(sig == "INT" ? SIGINT : sig == "TERM" ? SIGTERM : SIGKILL);
}

}  // namespace arthrosim::cli
