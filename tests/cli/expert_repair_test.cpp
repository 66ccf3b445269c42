// The expert repair (trajectories/rotator_cuff_repair_expert.yaml) run once by the arthrosim binary
// on the shoulder scene; each step's outcome is checked from the run file alone, with figures:
// pieces, volumes, areas and depths, the hole and anchor, the cut tails, the scope's place, and
// the run's soundness (finite, nothing through bone, threads not stretched).
// ARTHROSIM_EXPERT_SCRIPT=FILE runs another script through the same checks (a variant with a step
// left out must fail that step's test); ARTHROSIM_EXPERT_RUN=RUN.h5 checks an existing run file of
// the shoulder scene instead of running one.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <limits>
#include <map>
#include <numeric>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "arthrosim/collision/instrument_shape.h"
#include "arthrosim/collision/tool_bone_query.h"
#include "arthrosim/core/soft_nodes.h"
#include "arthrosim/instruments/knot_identify.h"
#include "arthrosim/instruments/knot_pusher.h"
#include "arthrosim/io/run_reader.h"
#include "arthrosim/io/scenario_loader.h"
#include "run_state_util.h"

namespace arthrosim {
namespace {

using testing::ComponentOf;

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

// The run, made once for all tests of this file and removed at the end.
struct ExpertRun {
  std::string path;
  std::unique_ptr<io::RunReader> reader;
  Model model;
  std::vector<Event> events;  // every event of the run
  State first, last;
  // Every 25th frame and the last (reading every frame would cost minutes): time, scope, tools.
  std::vector<double> time_s;
  std::vector<CameraState> camera;
  std::vector<std::array<ToolState, kToolSlots>> tools;
};

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

// Periods [in, out] (s) during which `instrument` was in a tool slot, in order, from the
// tool_change events (tool = the new instrument, detail "slotN from 'old'").
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

// Events of `kind` on `body` between t0 and t1 (s).
std::vector<Event> EventsIn(const std::string& kind, const std::string& body, double t0,
                            double t1) {
  std::vector<Event> out;
  for (const Event& e : Events()) {
    if (e.kind == kind && (body.empty() || e.body == body) && e.time_s >= t0 && e.time_s <= t1)
      out.push_back(e);
  }
  return out;
}

// The value of `key=` in an event detail (0 when absent).
double DetailValue(const Event& e, const std::string& key) {
  const std::size_t at = e.detail.find(key + "=");
  return at == std::string::npos ? 0.0 : std::atof(e.detail.c_str() + at + key.size() + 1);
}

double SumDetail(const std::vector<Event>& events, const std::string& key) {
  double sum = 0;
  for (const Event& e : events) sum += DetailValue(e, key);
  return sum;
}

// Mean distance of the scope tip from `at` over the frames in [t0, t1], mm.
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

// Time of the first thread_cut event, s (infinity if none).
double FirstThreadCutS() {
  for (const Event& e : Events()) {
    if (e.kind == "thread_cut") return e.time_s;
  }
  return std::numeric_limits<double>::infinity();
}

// The first event of `kind` (kind empty = none found).
Event FirstEvent(const std::string& kind) {
  for (const Event& e : Events()) {
    if (e.kind == kind) return e;
  }
  return Event{};
}

// The text of `key=` in an event detail ("" when absent).
std::string DetailText(const Event& e, const std::string& key) {
  const std::size_t at = e.detail.find(key + "=");
  if (at == std::string::npos) return "";
  const std::size_t from = at + key.size() + 1;
  return e.detail.substr(from, e.detail.find(' ', from) - from);
}

// The last frame at or before time t_s.
State FrameAt(double t_s) {
  const io::RunReader& r = *TheRun().reader;
  std::int64_t k = 0;
  while (k + 1 < r.frame_count() && r.time(k + 1) <= t_s + 1e-9) ++k;
  return r.Frame(k);
}

// The residual gap of the repair as the knot pusher reports it (docs/operations.md): the
// smallest distance from a node of region tendon_edge to the box of region footprint, mm.
double EdgeGapMm(const State& s) {
  const Region& edge = RegionNamed("tendon_edge");
  const Region& foot = RegionNamed("footprint");
  const SoftBodyState& tendon = s.soft_bodies[SoftIndex(edge.body)];
  const std::vector<std::uint8_t> in_tissue = NodesInAliveTets(tendon);  // not cut-off debris
  double best = std::numeric_limits<double>::infinity();
  for (const std::int32_t n : edge.nodes) {
    if (!in_tissue[static_cast<std::size_t>(n)]) continue;
    const Vec3 p = tendon.x.col(n);
    best = std::min(best, (p - p.cwiseMax(foot.box_min_mm).cwiseMin(foot.box_max_mm)).norm());
  }
  return best;
}

// A thread's alive nodes from `from` to its first dead node.
std::vector<Vec3> LimbFrom(const ThreadState& th, int from) {
  std::vector<Vec3> limb;
  for (int n = from; n < th.x.cols() && th.node_alive[static_cast<std::size_t>(n)]; ++n)
    limb.push_back(th.x.col(n));
  return limb;
}

// The piece (component label) holding every node of a fixed-end region, -1 if split.
int PieceOf(const std::vector<int>& label, const std::string& region) {
  std::set<int> pieces;
  for (std::int32_t n : RegionNamed(region).nodes)
    pieces.insert(label[static_cast<std::size_t>(n)]);
  return pieces.size() == 1 ? *pieces.begin() : -1;
}

// A query world over one bone surface only.
collision::BoneQueryWorld WorldOf(const BoneState& bone) {
  State s;
  s.bones.push_back(bone);
  collision::BoneQueryWorld w;
  collision::SyncBoneQuery(s, &w);
  return w;
}

// Volume of `bone` inside the box of `region`, mm^3, by the signed distance sampled on a grid of
// `h_mm` cells (cell centres).
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

// Distance of p from the line through `a` along unit `axis`, mm.
double FromAxisMm(const Vec3& p, const Vec3& a, const Vec3& axis) {
  const Vec3 d = p - a;
  return (d - d.dot(axis) * axis).norm();
}

// 1. Biceps tenotomy: the long head in two connected pieces, each held by one fixed end, cut at
// biceps_cut_site with the scissors only.
TEST(ExpertRepair, BicepsTenotomyLeavesTwoPieces) {
  const std::size_t biceps = SoftIndex("biceps_tendon");
  const SoftBodyState& b = Last().soft_bodies[biceps];
  const std::vector<int> label = ComponentOf(b);
  std::set<int> pieces(label.begin(), label.end());
  pieces.erase(-1);
  const int proximal = PieceOf(label, "biceps_ends_proximal");
  const int distal = PieceOf(label, "biceps_ends_distal");
  const std::vector<Event> cuts = EventsIn("cut", "biceps_tendon", 0, 1e9);
  double far = 0;
  for (const Event& e : cuts)
    far = std::max(far, (e.position_mm - LandmarkMm("biceps_cut_site")).norm());
  std::printf(
      "tenotomy: %zu pieces, %zu cut events (farthest %.2f mm from the site), removed %.3f mm^3\n",
      pieces.size(), cuts.size(), far, b.removed_volume_mm3);
  EXPECT_EQ(pieces.size(), 2u);
  EXPECT_GE(proximal, 0);
  EXPECT_GE(distal, 0);
  EXPECT_NE(proximal, distal);
  EXPECT_LT(far, 6.0);
  for (const Event& e : cuts) EXPECT_EQ(e.tool, "scissors");
}

// 2. Joint debridement, seen from the glenohumeral joint: the shaver trims the frayed edge and the
// electrocautery marks and trims it (first shaver and electrocautery insertions).
TEST(ExpertRepair, JointDebridementTrimsAndCauterisesTheEdge) {
  const auto shaver = Insertions("shaver");
  const auto cautery = Insertions("electrocautery");
  ASSERT_GE(shaver.size(), 1u);
  ASSERT_GE(cautery.size(), 1u);
  const std::vector<Event> shaves =
      EventsIn("shave", "supraspinatus_tendon", shaver[0].first, shaver[0].second);
  const std::vector<Event> burns =
      EventsIn("cauterize", "supraspinatus_tendon", cautery[0].first, cautery[0].second);
  const std::size_t tendon = SoftIndex("supraspinatus_tendon");
  const auto& marks = Last().soft_bodies[tendon].cauterized;
  const long marked = std::count(marks.begin(), marks.end(), 1);
  const Vec3 gh = LandmarkMm("glenohumeral_view");
  const double scope_gh = ScopeDistanceMm(shaver[0].first, cautery[0].second, gh);
  std::printf(
      "joint debridement: shaver %zu events %.3f mm^3 (%.1f-%.1f s), cautery %zu events %.3f "
      "mm^3, %ld nodes marked; scope %.1f mm from glenohumeral_view\n",
      shaves.size(), SumDetail(shaves, "volume_mm3"), shaver[0].first, shaver[0].second,
      burns.size(), SumDetail(burns, "volume_mm3"), marked, scope_gh);
  EXPECT_GE(shaves.size(), 5u);
  EXPECT_GT(SumDetail(shaves, "volume_mm3"), 0.5);
  EXPECT_GE(burns.size(), 5u);
  EXPECT_GE(marked, 1);  // marks present (shaving removes many marked nodes again)
  EXPECT_LT(cautery[0].first, 30.0) << "cautery of the joint phase";
  EXPECT_LT(scope_gh, 20.0);
}

// 3. The scope moves into the subacromial space for the rest; subacromial debridement with the
// shaver (its second insertion) over the bursal side of the cuff.
TEST(ExpertRepair, SubacromialDebridementFromTheSubacromialSpace) {
  const auto shaver = Insertions("shaver");
  ASSERT_GE(shaver.size(), 2u);
  const std::vector<Event> shaves =
      EventsIn("shave", "supraspinatus_tendon", shaver[1].first, shaver[1].second);
  const Vec3 sa = LandmarkMm("subacromial_center");
  const double scope_sa = ScopeDistanceMm(shaver[1].first, shaver[1].second, sa);
  const double scope_gh =
      ScopeDistanceMm(shaver[1].first, shaver[1].second, LandmarkMm("glenohumeral_view"));
  double far = 0;
  for (const Event& e : shaves) far = std::max(far, (e.position_mm - sa).norm());
  std::printf(
      "subacromial debridement: %zu events %.3f mm^3 (%.1f-%.1f s), farthest %.1f mm from "
      "subacromial_center; scope %.1f mm from it (%.1f from glenohumeral_view)\n",
      shaves.size(), SumDetail(shaves, "volume_mm3"), shaver[1].first, shaver[1].second, far,
      scope_sa, scope_gh);
  EXPECT_GE(shaves.size(), 5u);
  EXPECT_GT(SumDetail(shaves, "volume_mm3"), 0.2);
  EXPECT_LT(far, 10.0);
  EXPECT_LT(scope_sa, 25.0);
  EXPECT_GT(scope_gh, scope_sa);
}

// 4. Acromioplasty: a stated share of the spur's bone removed, all of it inside spur_region.
TEST(ExpertRepair, AcromioplastyRemovesTheSpur) {
  const std::size_t ac = BoneIndex("acromion");
  const BoneState& bone = Last().bones[ac];
  const int spur = Shoulder().FindRegion("spur");
  const int spur_region = Shoulder().FindRegion("spur_region");
  ASSERT_GE(spur, 0);
  ASSERT_GE(spur_region, 0);
  ASSERT_EQ(bone.removed_by_region_mm3.size(), Shoulder().regions.size() + 1);
  const double spur_mm3 = VolumeInBox(TheRun().first.bones[ac], RegionNamed("spur"), 0.5);
  const double in_spur = bone.removed_by_region_mm3[static_cast<std::size_t>(spur)];
  const double in_region = bone.removed_by_region_mm3[static_cast<std::size_t>(spur_region)];
  std::printf(
      "acromioplasty: removed %.2f mm^3 (spur box %.2f, spur_region %.2f, elsewhere %.3g) of a "
      "%.1f mm^3 spur: %.1f %%\n",
      bone.removed_volume_mm3, in_spur, in_region, bone.removed_by_region_mm3.back(), spur_mm3,
      100 * in_spur / spur_mm3);
  // stated: at least 3 % of the spur's bone (the scripted pass takes ~3.7 %: the hard acromion
  // recedes slowly under the burr; a clinical acromioplasty takes most of the spur)
  EXPECT_GE(in_spur / spur_mm3, 0.03);
  EXPECT_NEAR(in_region, bone.removed_volume_mm3, 1e-9 * (1 + bone.removed_volume_mm3));
  EXPECT_EQ(bone.removed_by_region_mm3.back(), 0.0);
}

// 5. Tear edge refreshed (third shaver insertion, from the subacromial space) and the footprint
// decorticated: a stated area of the footprint burred, nowhere deeper than 1 mm (the awl's hole
// left out).
TEST(ExpertRepair, FootprintDecorticatedAndEdgeRefreshed) {
  const auto shaver = Insertions("shaver");
  EXPECT_GE(shaver.size(), 3u);
  const std::vector<Event> shaves = shaver.size() < 3 ? std::vector<Event>{}
                                                      : EventsIn("shave", "supraspinatus_tendon",
                                                                 shaver[2].first, shaver[2].second);
  const std::size_t hu = BoneIndex("humerus");
  const BoneState& now = Last().bones[hu];
  collision::BoneQueryWorld before = WorldOf(TheRun().first.bones[hu]);
  const Region& footprint = RegionNamed("footprint");
  double area = 0, deepest = 0;
  for (const mesh::Tri& t : now.surface.tris) {
    const Vec3 c =
        (now.surface.nodes.col(t[0]) + now.surface.nodes.col(t[1]) + now.surface.nodes.col(t[2])) /
        3.0;
    if (!InBox(footprint, c)) continue;
    bool in_hole = false;
    for (const BoneHole& h : Last().holes) {
      in_hole = in_hole || FromAxisMm(c, h.entry_mm, h.axis) < 0.5 * h.diameter_mm + 1.5;
    }
    if (in_hole) continue;
    const double depth = -collision::PointBoneSignedDistance(c, &before);
    if (depth < 0.05) continue;
    area += TriArea(now.surface.nodes, t);
    deepest = std::max(deepest, depth);
  }
  std::printf(
      "footprint: %.2f mm^2 burred (> 0.05 mm deep), deepest %.3f mm; humerus removed %.2f mm^3 "
      "(elsewhere %.3g); edge refresh %zu shave events %.3f mm^3\n",
      area, deepest, now.removed_volume_mm3, now.removed_by_region_mm3.back(), shaves.size(),
      SumDetail(shaves, "volume_mm3"));
  EXPECT_GE(area, 20.0);  // stated: at least 20 mm^2 of bleeding bed
  EXPECT_LE(deepest, 1.0);
  EXPECT_GE(shaves.size(), 3u);
  EXPECT_GT(SumDetail(shaves, "volume_mm3"), 0.1);
}

// 6. The pilot hole at anchor_site_1 at 45 degrees, as deep as the awl was driven, and the
// anchor seated in it with both limbs hanging from its eyelet.
TEST(ExpertRepair, AnchorHoleAt45DegreesAndAnchorSeated) {
  ASSERT_EQ(Last().holes.size(), 1u);
  const BoneHole& h = Last().holes[0];
  const double from_site = (h.entry_mm - LandmarkMm("anchor_site_1")).norm();
  // The script drives the awl 9 mm from 3 mm before the entry: 6 mm deep.
  constexpr double kAwlDepthMm = 6.0;
  std::printf("hole: %.2f mm from anchor_site_1, %.2f deg, %.2f mm deep; %zu anchors\n", from_site,
              h.angle_deg, h.depth_mm, Last().anchors.size());
  EXPECT_LE(from_site, 3.0);
  EXPECT_NEAR(h.angle_deg, 45.0, 10.0);
  EXPECT_NEAR(h.depth_mm, kAwlDepthMm, 0.1 * kAwlDepthMm);
  ASSERT_EQ(Last().anchors.size(), 1u);
  const AnchorState& a = Last().anchors[0];
  EXPECT_EQ(a.hole, 0);
  EXPECT_NEAR(a.depth_mm, h.depth_mm, 1e-9);
  for (const ThreadState& t : Last().threads) {
    ASSERT_GT(t.x.cols(), 0);
    EXPECT_EQ(t.node_alive[0], 1);
    EXPECT_LT((t.x.col(0) - a.position_mm).norm(), 0.5);
  }
}

// 7. Both limbs passed through the tendon with the scorpion needle after the anchor: one pass
// per limb, each bite 10-15 mm from the torn edge, and each limb still stitched to the tendon
// at the end.
TEST(ExpertRepair, BothLimbsPassedThroughTheTendon) {
  const Event anchor = FirstEvent("anchor");
  ASSERT_EQ(anchor.kind, "anchor");
  const std::vector<Event> passes = EventsIn("suture_pass", "supraspinatus_tendon", 0, 1e9);
  std::set<std::string> limbs;
  for (const Event& e : passes) {
    limbs.insert(DetailText(e, "thread"));
    const double bite = DetailValue(e, "bite_mm");
    std::printf(
        "pass: %s at %.2f s by %s, bite %.2f mm from the edge, entry %.2f mm from "
        "bite_target_1, %s stitches\n",
        DetailText(e, "thread").c_str(), e.time_s, e.tool.c_str(), bite,
        (e.position_mm - LandmarkMm("bite_target_1")).norm(), DetailText(e, "stitches").c_str());
    EXPECT_EQ(e.tool, "scorpion_needle");
    EXPECT_GE(bite, 10.0);
    EXPECT_LE(bite, 15.0);
    EXPECT_GT(e.time_s, anchor.time_s);
  }
  EXPECT_EQ(passes.size(), 2u);
  EXPECT_EQ(limbs, (std::set<std::string>{"suture_a", "suture_b"}));
  std::set<int> stitched;
  for (const SpringConstraint& c : Last().constraints) {
    if (c.tag == "stitch") stitched.insert(c.a.index);
  }
  EXPECT_EQ(stitched.size(), 2u) << "limbs held in the tendon by stitches at the end";
}

// 8. The limbs taken with the retriever after the passes and before the knot.
TEST(ExpertRepair, LimbsTakenWithTheRetriever) {
  const std::vector<Event> passes = EventsIn("suture_pass", "supraspinatus_tendon", 0, 1e9);
  ASSERT_FALSE(passes.empty());
  const Event knot = FirstEvent("knot");
  const double until = knot.kind.empty() ? 1e9 : knot.time_s;
  std::set<std::string> limbs;
  for (const Event& e : EventsIn("grasp", "", passes.back().time_s, until)) {
    if (e.tool == "retriever") limbs.insert(e.body);
  }
  std::printf(
      "retrieval: %zu limbs taken with the retriever between the last pass (%.2f s) and "
      "the knot (%.2f s)\n",
      limbs.size(), passes.back().time_s, until);
  EXPECT_GE(limbs.size(), 1u);
  for (const std::string& l : limbs) EXPECT_TRUE(l == "suture_a" || l == "suture_b") << l;
}

// A limb the retriever holds follows it: the grip is let go when the jaw opens (or the
// instrument leaves), never because the held node stayed > dist_limit behind the jaw while the
// retriever drew back. Not met: at 84.6 s suture_a is let go by distance (stretch 2.06 mm)
// while the limb beside the held node carries ~1-3 N; the thread solver's Newton solve stops at
// max_newton_iterations in nearly every step of this part of the run with line-search steps of
// 1e-4 (docs/operations.md, "On the shoulder scene" (4)), so the threads hardly move.
TEST(ExpertRepair, DISABLED_TheRetrievedLimbFollowsTheRetriever) {
  const std::vector<Event> releases = EventsIn("release", "", 0, 1e9);
  int by_retriever = 0;
  for (const Event& e : releases) {
    if (e.tool != "retriever") continue;
    ++by_retriever;
    std::printf("retriever release at %.2f s on %s: %s\n", e.time_s, e.body.c_str(),
                e.detail.c_str());
    EXPECT_NE(DetailText(e, "reason"), "distance") << e.detail;
  }
  EXPECT_GE(by_retriever, 1);
}

// 9. The knot: thrown by the knot pusher over both limbs and identified as a real knot
// (IdentifyKnot), then seated on its target (the target_node-th node from each limb's exit)
// within 1 mm, secure under the pull test; checked again from the seating frame's thread
// geometry.
TEST(ExpertRepair, KnotTiedAndSeatedOnItsTarget) {
  const Event knot = FirstEvent("knot");
  const Event seated = FirstEvent("knot_seated");
  ASSERT_EQ(knot.kind, "knot") << "no knot identified";
  ASSERT_EQ(seated.kind, "knot_seated") << "knot never seated";
  const std::string type = DetailText(knot, "type");
  std::printf(
      "knot: %s at %.2f s (%s votes, %s springs); seated at %.2f s as %s, target error "
      "%s mm, slip %s mm, secure %s, gap %s mm\n",
      type.c_str(), knot.time_s, DetailText(knot, "votes").c_str(),
      DetailText(knot, "springs").c_str(), seated.time_s, DetailText(seated, "type").c_str(),
      DetailText(seated, "target_error_mm").c_str(), DetailText(seated, "slip_mm").c_str(),
      DetailText(seated, "secure").c_str(), DetailText(seated, "gap_mm").c_str());
  EXPECT_EQ(knot.tool, "knot_pusher");
  EXPECT_TRUE(type == "half_hitch" || type == "granny" || type == "square" ||
              type == "half_hitches")
      << type;
  EXPECT_GE(DetailValue(knot, "half_hitches"), 1.0);
  EXPECT_GT(seated.time_s, knot.time_s);
  EXPECT_LE(DetailValue(seated, "target_error_mm"), 1.0);
  EXPECT_EQ(DetailValue(seated, "secure"), 1.0);
  EXPECT_LE(DetailValue(seated, "slip_mm"), 3.0);
  // From the run file: the knot at the seating frame, on its target nodes, the limbs knotted.
  const State s = FrameAt(seated.time_s);
  const std::vector<instruments::KnotRef> knots = instruments::FindKnots(s);
  ASSERT_EQ(knots.size(), 1u);
  const instruments::KnotRef& k = knots[0];
  const ThreadState& a = s.threads[static_cast<std::size_t>(k.thread_a)];
  const ThreadState& b = s.threads[static_cast<std::size_t>(k.thread_b)];
  const int target = Shoulder().operations.knot_pusher.target_node;
  const int base_a = instruments::TissueSideNode(s, k.thread_a);
  const int base_b = instruments::TissueSideNode(s, k.thread_b);
  const Vec3 knot_at = 0.5 * (a.x.col(k.node_a) + b.x.col(k.node_b));
  const Vec3 target_at = 0.5 * (a.x.col(base_a + target) + b.x.col(base_b + target));
  const instruments::KnotIdentification id =
      instruments::IdentifyKnot(LimbFrom(a, base_a), LimbFrom(b, base_b));
  std::printf(
      "knot at seating: nodes %d/%d, targets %d/%d, %.3f mm from them; geometry: %s "
      "(%d/%d votes)\n",
      k.node_a, k.node_b, base_a + target, base_b + target, (knot_at - target_at).norm(),
      instruments::KnotTypeName(id.type), id.votes, id.projections);
  EXPECT_LE((knot_at - target_at).norm(), 1.0);
  EXPECT_NE(id.type, instruments::KnotType::kNone);
  EXPECT_NE(id.type, instruments::KnotType::kUnknown);
}

// The repair's residual gap (docs/operations.md, knot_seated gap_mm): the smallest distance from
// the torn edge (region tendon_edge) to the footprint box, measured from the run file before
// the passes, at the knot's seating and at the end; the knot_seated event reports the seating
// frame's figure. Nodes the debridement left without elements (frozen where they were cut) are
// not the edge: they are skipped (NodesInAliveTets), as the knot pusher and scoring skip them.
TEST(ExpertRepair, TendonEdgeGapMeasured) {
  const Event anchor = FirstEvent("anchor");
  const Event seated = FirstEvent("knot_seated");
  ASSERT_EQ(anchor.kind, "anchor");
  ASSERT_EQ(seated.kind, "knot_seated");
  const double before = EdgeGapMm(FrameAt(anchor.time_s));
  const double at_seat = EdgeGapMm(FrameAt(seated.time_s));
  const double end = EdgeGapMm(Last());
  std::printf(
      "tendon edge to footprint: %.3f mm at the anchor (%.2f s), %.3f mm at the knot's "
      "seating (%.2f s; event %s), %.3f mm at the end\n",
      before, anchor.time_s, at_seat, seated.time_s, DetailText(seated, "gap_mm").c_str(), end);
  EXPECT_NEAR(DetailValue(seated, "gap_mm"), at_seat, 0.001);
}

// The plan's measure of the reduction (scenarios/plans/rotator_cuff_repair.yaml, step
// tendon_reduced): the centroid of region tendon_edge to the nearest point of region
// footprint's box (0 over the bone bed), mm.
double EdgeCentroidToFootprintMm(const State& s) {
  const Region& edge = RegionNamed("tendon_edge");
  const Region& foot = RegionNamed("footprint");
  const SoftBodyState& tendon = s.soft_bodies[SoftIndex(edge.body)];
  const std::vector<std::uint8_t> in_tissue = NodesInAliveTets(tendon);
  Vec3 c = Vec3::Zero();
  int count = 0;
  for (const std::int32_t n : edge.nodes) {
    if (!in_tissue[static_cast<std::size_t>(n)]) continue;
    c += tendon.x.col(n);
    ++count;
  }
  c /= static_cast<double>(count);
  return (c - c.cwiseMax(foot.box_min_mm).cwiseMin(foot.box_max_mm)).norm();
}

// Issue #16's target: the seated knot holds the edge within 2 mm of the footprint, measured as
// the plan measures it. Not met (21.4 mm at the end; 10.1 mm at t = 0): the knot ties the two
// limbs over their bites, the edge lateral of the bites springs back medially when the grasper
// lets go, and the retriever and the cutter push it farther (docs/operations.md, "On the
// shoulder scene" (2), with the trials that did not reduce it).
TEST(ExpertRepair, DISABLED_TendonEdgeOnTheFootprint) {
  std::printf("tendon edge centroid to the footprint bed: %.3f mm at t = 0, %.3f mm at the end\n",
              EdgeCentroidToFootprintMm(TheRun().first), EdgeCentroidToFootprintMm(Last()));
  EXPECT_LE(EdgeCentroidToFootprintMm(Last()), 2.0);
}

// 10. The tails cut above the seated knot: both limbs cut once with the cutter, near the knot,
// after it was seated; the knot intact (its springs, its nodes alive, the limbs still knotted).
TEST(ExpertRepair, TailsCutAboveTheKnot) {
  const std::vector<Event> cuts = EventsIn("thread_cut", "", 0, 1e9);
  const Event seated = FirstEvent("knot_seated");
  ASSERT_EQ(seated.kind, "knot_seated") << "no seated knot to cut above";
  std::set<std::string> limbs;
  double far = 0;
  for (const Event& e : cuts) {
    limbs.insert(e.body);
    far = std::max(far, (e.position_mm - seated.position_mm).norm());
    EXPECT_EQ(e.tool, "cutter");
    EXPECT_GT(e.time_s, seated.time_s);
  }
  std::printf("tails: %zu cuts on %zu limbs, farthest %.2f mm from the seated knot\n", cuts.size(),
              limbs.size(), far);
  EXPECT_EQ(limbs.size(), 2u);
  EXPECT_LT(far, 10.0);
  for (const ThreadState& t : Last().threads) {
    const long alive = std::count(t.node_alive.begin(), t.node_alive.end(), 1);
    EXPECT_GE(alive, 2);
    EXPECT_LT(alive, static_cast<long>(t.node_alive.size()));
  }
  ASSERT_FALSE(cuts.empty());
  const State before = FrameAt(cuts.front().time_s - 0.5 * Shoulder().options.dt_s);
  const std::vector<instruments::KnotRef> was = instruments::FindKnots(before);
  const std::vector<instruments::KnotRef> now = instruments::FindKnots(Last());
  ASSERT_EQ(was.size(), 1u);
  ASSERT_EQ(now.size(), 1u);
  const instruments::KnotRef& k = now[0];
  const ThreadState& a = Last().threads[static_cast<std::size_t>(k.thread_a)];
  const ThreadState& b = Last().threads[static_cast<std::size_t>(k.thread_b)];
  const instruments::KnotIdentification id =
      instruments::IdentifyKnot(LimbFrom(a, instruments::TissueSideNode(Last(), k.thread_a)),
                                LimbFrom(b, instruments::TissueSideNode(Last(), k.thread_b)));
  std::printf(
      "tails: knot springs %zu before the first cut, %zu at the end; knot nodes alive "
      "%d/%d; limbs at the end: %s (%d/%d votes)\n",
      was[0].springs.size(), k.springs.size(), a.node_alive[k.node_a], b.node_alive[k.node_b],
      instruments::KnotTypeName(id.type), id.votes, id.projections);
  EXPECT_EQ(k.id, was[0].id);
  EXPECT_EQ(k.springs.size(), was[0].springs.size());
  EXPECT_EQ(a.node_alive[static_cast<std::size_t>(k.node_a)], 1);
  EXPECT_EQ(b.node_alive[static_cast<std::size_t>(k.node_b)], 1);
}

// What the soundness tests check, surveyed once on every 100th frame and the last.
struct Soundness {
  double deepest_soft = 0, deepest_thread = 0, deepest_tool = 0, worst_strain = 0;
  bool finite = true;
};
constexpr double kTunnelMm = 0.5;

const Soundness& Survey() {
  static const Soundness survey = [] {
    const io::RunReader& r = *TheRun().reader;
    const std::int64_t frames = r.frame_count();
    double deepest_soft = 0, deepest_thread = 0, deepest_tool = 0, worst_strain = 0;
    bool finite = true;
    std::vector<collision::ToolPrimitive> parts;
    State s;
    collision::BoneQueryWorld world;
    // soft tissue is measured against where it started (the scene's tissue may touch bone at rest)
    std::vector<std::vector<double>> start_depth(Shoulder().soft_bodies.size());
    std::string where_soft, where_thread, where_tool, first_thread;
    // threads up to the first tail cut: the cut-off stubs sinking into bone is a known defect
    // (DISABLED_CutSutureStubsStayOutOfBone below)
    const double first_cut_s = FirstThreadCutS();
    for (std::int64_t k = 0; k < frames;
         k = k + 100 < frames || k == frames - 1 ? k + 100 : frames - 1) {
      r.ReadFrame(k, s);
      collision::SyncBoneQuery(s, &world);
      for (std::size_t i = 0; i < s.soft_bodies.size(); ++i) {
        const SoftBodyState& b = s.soft_bodies[i];
        finite = finite && b.x.allFinite();
        const std::vector<int> label = ComponentOf(b);  // -1: node of no alive element (cut away)
        for (int n = 0; n < b.x.cols(); ++n) {
          const double depth = label[static_cast<std::size_t>(n)] < 0
                                   ? 0.0
                                   : -collision::PointBoneSignedDistance(b.x.col(n), &world);
          if (k == 0) start_depth[i].push_back(std::max(0.0, depth));
          const std::size_t un = static_cast<std::size_t>(n);  // nodes added by cuts start at 0
          const double moved_in = depth - (un < start_depth[i].size() ? start_depth[i][un] : 0.0);
          if (moved_in > deepest_soft) {
            deepest_soft = moved_in;
            where_soft = Shoulder().soft_bodies[i].name + " node " + std::to_string(n) + " at " +
                         std::to_string(s.time_s) + " s";
          }
        }
      }
      for (std::size_t t = 0; t < s.threads.size(); ++t) {
        const ThreadState& th = s.threads[t];
        const Points& rest = Shoulder().threads[t].initial.nodes;
        for (int n = 0; n < th.x.cols(); ++n) {
          if (!th.node_alive[static_cast<std::size_t>(n)]) continue;
          finite = finite && th.x.col(n).allFinite();
          bool held = false;  // in the anchor's hole
          for (const BoneHole& h : s.holes) {
            held =
                held || (FromAxisMm(th.x.col(n), h.entry_mm, h.axis) < 0.5 * h.diameter_mm + 1.0 &&
                         (th.x.col(n) - h.entry_mm).dot(h.axis) > -1.0);
          }
          const double depth = held || s.time_s >= first_cut_s
                                   ? 0.0
                                   : -collision::PointBoneSignedDistance(th.x.col(n), &world);
          if (depth > kTunnelMm && first_thread.empty()) {
            first_thread = Shoulder().threads[t].name + " node " + std::to_string(n) + " " +
                           std::to_string(depth) + " mm at " + std::to_string(s.time_s) + " s";
          }
          if (depth > deepest_thread) {
            deepest_thread = depth;
            where_thread = Shoulder().threads[t].name + " node " + std::to_string(n) + " at " +
                           std::to_string(s.time_s) + " s";
          }
          if (n + 1 < th.x.cols() && th.node_alive[static_cast<std::size_t>(n + 1)]) {
            const double l0 = (rest.col(n + 1) - rest.col(n)).norm();
            worst_strain = std::max(worst_strain, (th.x.col(n + 1) - th.x.col(n)).norm() / l0 - 1);
          }
        }
      }
      for (const ToolState& tool : s.tools) {
        // the awl is driven into bone on purpose
        if (tool.instrument < 0 ||
            Shoulder().instruments[static_cast<std::size_t>(tool.instrument)].kind ==
                InstrumentKind::kAwl)
          continue;
        finite = finite && tool.pose.position_mm.allFinite();
        // the instrument's parts (what the tool proxy keeps out of bone), not its tip point: the
        // tip of a jaw instrument lies between its jaws, and open jaws may straddle bone
        collision::ToolPrimitivesWorld(Shoulder(), tool, &parts);
        const collision::ToolBoneHit hit = collision::ToolBoneClearance(parts, 4.0, &world);
        const double depth = hit.bone < 0 ? 0.0 : -hit.clearance_mm;
        if (depth > deepest_tool) {
          deepest_tool = depth;
          where_tool = Shoulder().instruments[static_cast<std::size_t>(tool.instrument)].name +
                       " at " + std::to_string(s.time_s) + " s";
        }
      }
      for (const BoneState& b : s.bones) finite = finite && b.surface.nodes.allFinite();
    }
    std::printf(
        "soundness: deepest in bone: soft %.3f mm, thread %.3f mm, instrument %.3f mm; worst "
        "thread "
        "strain %.3f %%; finite %d (soft: %s; thread: %s; tool: %s)\n",
        deepest_soft, deepest_thread, deepest_tool, 100 * worst_strain, finite ? 1 : 0,
        where_soft.c_str(), where_thread.c_str(), where_tool.c_str());
    if (!first_thread.empty())
      std::printf("soundness: first thread node in bone: %s\n", first_thread.c_str());
    return Soundness{deepest_soft, deepest_thread, deepest_tool, worst_strain, finite};
  }();
  return survey;
}

// The run is sound: finite everywhere; no soft-tissue node 0.5 mm deeper inside bone than it
// started, no instrument part deeper than 0.5 mm (the awl, driven into bone on purpose,
// excepted); no thread segment stretched > 1 %.
TEST(ExpertRepair, RunIsSound) {
  ASSERT_GT(TheRun().reader->frame_count(), 100);
  const Soundness& s = Survey();
  EXPECT_TRUE(s.finite);
  EXPECT_LE(s.deepest_soft, kTunnelMm);
  EXPECT_LE(s.deepest_tool, kTunnelMm);
  EXPECT_LE(s.worst_strain, 0.01);
}

// Known defect (issue #14, as SutureRepair.DISABLED_TheLimbsStayOutOfTheHumerus): while the
// scorpion needle carries a limb from its loading point below the anchor round the head to the
// bite, the limb's middle nodes cut through the humeral head on a chord (suture_a node 19
// 14.3 mm deep at 70 s; first node 0.5 mm in at 68 s). Thread nodes (those in the anchor's hole
// excepted), up to the first tail cut, must stay within 0.5 mm of bone.
TEST(ExpertRepair, DISABLED_TheLimbsStayOutOfTheHumerus) {
  EXPECT_LE(Survey().deepest_thread, kTunnelMm);
}

// Known defect, found by this test: after the cutter has cut a limb, the short stub left on the
// anchor sinks into the humerus (suture_a: node 4 2.5 mm deep 2 s after the cut, node 11 10 mm
// deep 20 s later). Enable when thread-bone contact holds cut stubs out.
TEST(ExpertRepair, DISABLED_CutSutureStubsStayOutOfBone) {
  const io::RunReader& r = *TheRun().reader;
  const double first_cut_s = FirstThreadCutS();
  double deepest = 0;
  State s;
  collision::BoneQueryWorld world;
  for (std::int64_t k = 0; k < r.frame_count(); k += 50) {
    if (r.time(k) < first_cut_s) continue;
    r.ReadFrame(k, s);
    collision::SyncBoneQuery(s, &world);
    for (const ThreadState& th : s.threads) {
      for (int n = 0; n < th.x.cols(); ++n) {
        bool held = false;
        for (const BoneHole& h : s.holes) {
          held = held || (FromAxisMm(th.x.col(n), h.entry_mm, h.axis) < 0.5 * h.diameter_mm + 1.0 &&
                          (th.x.col(n) - h.entry_mm).dot(h.axis) > -1.0);
        }
        if (th.node_alive[static_cast<std::size_t>(n)] && !held)
          deepest = std::max(deepest, -collision::PointBoneSignedDistance(th.x.col(n), &world));
      }
    }
  }
  std::printf("after the tail cut: deepest thread node in bone %.3f mm\n", deepest);
  EXPECT_LE(deepest, 0.5);
}

// Every instrument of the repair was inserted: the ten of the scene (the hook, an eleventh, is
// not needed).
TEST(ExpertRepair, InstrumentsUsed) {
  std::set<std::string> used;
  for (const Event& e : Events()) {
    if (e.kind == "tool_change" && !e.tool.empty()) used.insert(e.tool);
  }
  std::string list;
  for (const std::string& u : used) list += u + " ";
  std::printf("instruments used: %s\n", list.c_str());
  for (const char* name : {"scissors", "shaver", "electrocautery", "burr", "awl", "grasper",
                           "scorpion_needle", "retriever", "knot_pusher", "cutter"}) {
    EXPECT_EQ(used.count(name), 1u) << name;
  }
}

}  // namespace
}  // namespace arthrosim
