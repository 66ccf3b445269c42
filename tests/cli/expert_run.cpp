// The expert repair's run, made (or read) once per test binary, and the helpers that read it
// (expert_run.h).
#include "expert_run.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <limits>
#include <set>

#include <gtest/gtest.h>

#include "arthrosim/io/scenario_loader.h"

namespace arthrosim::expert {
namespace {

namespace fs = std::filesystem;

const std::string kBinary = std::string(ARTHROSIM_BINARY_DIR) + "/src/cli/arthrosim";
const std::string kSource = ARTHROSIM_SOURCE_DIR;
const std::string kScene = kSource + "/scenarios/rotator_cuff_repair.yaml";

std::string Script() {
  const char* other = std::getenv("ARTHROSIM_EXPERT_SCRIPT");
  return other != nullptr && *other != '\0'
             ? std::string(other)
             : kSource + "/trajectories/rotator_cuff_repair_expert.yaml";
}

class RemoveRun : public ::testing::Environment {
 public:
  void TearDown() override {
    const fs::path p =
        fs::temp_directory_path() / ("arthrosim_expert_" + std::to_string(getpid()) + ".h5");
    fs::remove(p);
    fs::remove(fs::path(p).replace_extension(".xmf"));
  }
};
const auto* const kRemoveRun = ::testing::AddGlobalTestEnvironment(new RemoveRun);

}  // namespace

const ExpertRun& TheRun() {
  static ExpertRun* run = [] {
    auto* r = new ExpertRun;
    const char* given = std::getenv("ARTHROSIM_EXPERT_RUN");
    if (given != nullptr && *given != '\0') {
      r->path = given;
    } else {
      r->path =
          (fs::temp_directory_path() / ("arthrosim_expert_" + std::to_string(getpid()) + ".h5"))
              .string();
      const std::string cmd = kBinary + " run " + kScene + " --trajectory " + Script() +
                              " --quiet --out " + r->path + " > /dev/null 2>&1";
      EXPECT_EQ(std::system(cmd.c_str()), 0) << cmd;
    }
    r->reader = std::make_unique<io::RunReader>(r->path);
    const io::RunInfo& info = r->reader->info();
    r->model = io::LoadScenarioFromText(info.scenario_yaml, info.scenario_path);
    const std::int64_t last = r->reader->frame_count() - 1;
    r->events = r->reader->EventsUpTo(last);
    r->first = r->reader->Frame(0);
    r->last = r->reader->Frame(last);
    State s;
    for (std::int64_t k = 0;; k = std::min(k + 25, last)) {
      r->reader->ReadFrame(k, s);
      r->time_s.push_back(s.time_s);
      r->camera.push_back(s.camera);
      r->tools.push_back(s.tools);
      if (k == last) break;
    }
    return r;
  }();
  return *run;
}

const Model& Shoulder() { return TheRun().model; }
const State& Last() { return TheRun().last; }
const std::vector<Event>& Events() { return TheRun().events; }

Vec3 LandmarkMm(const std::string& name) {
  const int i = Shoulder().FindLandmark(name);
  EXPECT_GE(i, 0) << name;
  return i < 0 ? Vec3::Zero() : Shoulder().landmarks[static_cast<std::size_t>(i)].position_mm;
}

const Region& RegionNamed(const std::string& name) {
  const int i = Shoulder().FindRegion(name);
  EXPECT_GE(i, 0) << name;
  return Shoulder().regions[static_cast<std::size_t>(std::max(i, 0))];
}

bool InBox(const Region& r, const Vec3& p) {
  return (p.array() >= r.box_min_mm.array()).all() && (p.array() <= r.box_max_mm.array()).all();
}

std::size_t SoftIndex(const std::string& name) {
  const auto& names = TheRun().reader->info().soft_bodies;
  const auto it = std::find(names.begin(), names.end(), name);
  EXPECT_NE(it, names.end()) << name;
  return static_cast<std::size_t>(it - names.begin());
}

std::size_t BoneIndex(const std::string& name) {
  const int i = Shoulder().FindBone(name);
  EXPECT_GE(i, 0) << name;
  return static_cast<std::size_t>(std::max(i, 0));
}

std::vector<std::pair<double, double>> Insertions(const std::string& instrument) {
  std::vector<std::pair<double, double>> periods;
  std::array<int, kToolSlots> open{-1, -1};  // index into periods while it is in that slot
  for (const Event& e : Events()) {
    if (e.kind != "tool_change") continue;
    const int slot = e.detail.rfind("slot1", 0) == 0 ? 1 : 0;
    if (open[slot] >= 0) periods[static_cast<std::size_t>(open[slot])].second = e.time_s;
    open[slot] = -1;
    if (e.tool == instrument) {
      periods.push_back({e.time_s, 1e300});
      open[slot] = static_cast<int>(periods.size()) - 1;
    }
  }
  std::sort(periods.begin(), periods.end());
  return periods;
}

std::vector<Event> EventsIn(const std::string& kind, const std::string& body, double t0,
                            double t1) {
  std::vector<Event> out;
  for (const Event& e : Events()) {
    if (e.kind == kind && (body.empty() || e.body == body) && e.time_s >= t0 && e.time_s <= t1)
      out.push_back(e);
  }
  return out;
}

double DetailValue(const Event& e, const std::string& key) {
  const std::size_t at = e.detail.find(key + "=");
  return at == std::string::npos ? 0.0 : std::atof(e.detail.c_str() + at + key.size() + 1);
}

double SumDetail(const std::vector<Event>& events, const std::string& key) {
  double sum = 0;
  for (const Event& e : events) sum += DetailValue(e, key);
  return sum;
}

double ScopeDistanceMm(double t0, double t1, const Vec3& at) {
  const ExpertRun& r = TheRun();
  double sum = 0;
  int n = 0;
  for (std::size_t k = 0; k < r.time_s.size(); ++k) {
    if (r.time_s[k] < t0 || r.time_s[k] > t1) continue;
    sum += (r.camera[k].pose.position_mm - at).norm();
    ++n;
  }
  return n > 0 ? sum / n : 1e300;
}

double FirstThreadCutS() {
  for (const Event& e : Events()) {
    if (e.kind == "thread_cut") return e.time_s;
  }
  return std::numeric_limits<double>::infinity();
}

Event FirstEvent(const std::string& kind) {
  for (const Event& e : Events()) {
    if (e.kind == kind) return e;
  }
  return Event{};
}

std::string DetailText(const Event& e, const std::string& key) {
  const std::size_t at = e.detail.find(key + "=");
  if (at == std::string::npos) return "";
  const std::size_t from = at + key.size() + 1;
  return e.detail.substr(from, e.detail.find(' ', from) - from);
}

State FrameAt(double t_s) {
  const io::RunReader& r = *TheRun().reader;
  std::int64_t k = 0;
  while (k + 1 < r.frame_count() && r.time(k + 1) <= t_s + 1e-9) ++k;
  return r.Frame(k);
}

std::vector<Vec3> LimbFrom(const ThreadState& th, int from) {
  std::vector<Vec3> limb;
  for (int n = from; n < th.x.cols() && th.node_alive[static_cast<std::size_t>(n)]; ++n)
    limb.push_back(th.x.col(n));
  return limb;
}

int PieceOf(const std::vector<int>& label, const std::string& region) {
  std::set<int> pieces;
  for (std::int32_t n : RegionNamed(region).nodes)
    pieces.insert(label[static_cast<std::size_t>(n)]);
  return pieces.size() == 1 ? *pieces.begin() : -1;
}

collision::BoneQueryWorld WorldOf(const BoneState& bone) {
  State s;
  s.bones.push_back(bone);
  collision::BoneQueryWorld w;
  collision::SyncBoneQuery(s, &w);
  return w;
}

double VolumeInBox(const BoneState& bone, const Region& r, double h_mm) {
  collision::BoneQueryWorld w = WorldOf(bone);
  const Vec3 size = r.box_max_mm - r.box_min_mm;
  const int nx = static_cast<int>(std::ceil(size.x() / h_mm));
  const int ny = static_cast<int>(std::ceil(size.y() / h_mm));
  const int nz = static_cast<int>(std::ceil(size.z() / h_mm));
  long inside = 0;
  for (int i = 0; i < nx; ++i) {
    for (int j = 0; j < ny; ++j) {
      for (int k = 0; k < nz; ++k) {
        const Vec3 p = r.box_min_mm + h_mm * Vec3(i + 0.5, j + 0.5, k + 0.5);
        if (InBox(r, p) && collision::PointBoneSignedDistance(p, &w) < 0) ++inside;
      }
    }
  }
  return static_cast<double>(inside) * h_mm * h_mm * h_mm;
}

double TriArea(const Points& x, const mesh::Tri& t) {
  return 0.5 * (x.col(t[1]) - x.col(t[0])).cross(x.col(t[2]) - x.col(t[0])).norm();
}

double FromAxisMm(const Vec3& p, const Vec3& a, const Vec3& axis) {
  const Vec3 d = p - a;
  return (d - d.dot(axis) * axis).norm();
}

}  // namespace arthrosim::expert
