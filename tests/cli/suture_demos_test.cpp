// The suture repair on the shoulder scene (trajectories/ops/suture_repair.yaml): the anchor
// seated with the awl, then both of its limbs passed through the torn tendon with the scorpion
// needle while the grasper holds the torn edge. Run once by the arthrosim binary; every outcome is
// checked from the run file alone (the scenario only for its region and landmark definitions), as
// scoring reads it.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>

#include "arthrosim/collision/tool_bone_query.h"
#include "arthrosim/io/run_reader.h"
#include "arthrosim/io/run_writer.h"
#include "arthrosim/io/scenario_loader.h"
#include "run_state_util.h"

namespace arthrosim {
namespace {

using testing::EndAt;

const std::string kSource = ARTHROSIM_SOURCE_DIR;
const std::string kScene = kSource + "/scenarios/rotator_cuff_repair.yaml";

std::vector<Event> OfKind(const std::vector<Event>& events, const std::string& kind) {
  std::vector<Event> out;
  for (const Event& e : events)
    if (e.kind == kind) out.push_back(e);
  return out;
}

double Detail(const Event& e, const std::string& key) {
  const std::size_t at = e.detail.find(key + "=");
  EXPECT_NE(at, std::string::npos) << key << " in " << e.detail;
  return at == std::string::npos ? std::nan("") : std::atof(e.detail.c_str() + at + key.size() + 1);
}

std::string DetailText(const Event& e, const std::string& key) {
  const std::size_t at = e.detail.find(key + "=");
  if (at == std::string::npos) return "";
  const std::size_t from = at + key.size() + 1;
  return e.detail.substr(from, e.detail.find(' ', from) - from);
}

Vec3 DetailPoint(const Event& e, const std::string& key) {
  Vec3 p = Vec3::Constant(std::nan(""));
  const std::size_t at = e.detail.find(key + "=");
  if (at != std::string::npos)
    std::sscanf(e.detail.c_str() + at + key.size() + 1, "%lf,%lf,%lf", &p.x(), &p.y(), &p.z());
  return p;
}

Vec3 Centroid(const Points& x, const std::vector<std::int32_t>& nodes) {
  Vec3 c = Vec3::Zero();
  for (const std::int32_t n : nodes) c += x.col(n);
  return c / static_cast<double>(nodes.size());
}

// Distance from p to the nearest node of region `r` in frame s (the torn edge), mm.
double ToRegionNodesMm(const State& s, int body, const Region& r, const Vec3& p) {
  double best = std::numeric_limits<double>::infinity();
  for (const std::int32_t n : r.nodes)
    best = std::min(best, (s.soft_bodies[static_cast<std::size_t>(body)].x.col(n) - p).norm());
  return best;
}

// The run of trajectories/ops/suture_repair.yaml, made once by the fixture test
// Run.ops_suture_repair (tests/cli/CMakeLists.txt) and shared with its golden comparison.
class SutureRepair : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    path_ = std::string(ARTHROSIM_BINARY_DIR) + "/test_runs/ops_suture_repair.h5";
    status_ = std::filesystem::exists(path_) ? 0 : 1;
  }
  void SetUp() override {
    ASSERT_EQ(status_, 0) << path_ << ": run by the CTest Run.ops_suture_repair";
  }

  static std::string path_;
  static int status_;
};
std::string SutureRepair::path_;
int SutureRepair::status_ = -1;

TEST_F(SutureRepair, BothLimbsPassThroughTheTendon10To15MmFromTheTornEdge) {
  const Model model = io::LoadScenario(kScene);
  io::RunReader run(path_);
  const std::int64_t last = run.frame_count() - 1;
  const std::vector<Event> events = run.EventsUpTo(last);
  ASSERT_EQ(OfKind(events, "anchor").size(), 1u) << "the anchor first, as in awl.yaml";
  const std::vector<Event> passes = OfKind(events, "suture_pass");
  ASSERT_EQ(passes.size(), 2u);
  EXPECT_GT(passes[0].step, OfKind(events, "anchor")[0].step);
  EXPECT_NE(DetailText(passes[0], "thread"), DetailText(passes[1], "thread")) << "one per limb";
  const int tendon = model.FindSoftBody("supraspinatus_tendon");
  const Region& edge = model.regions[static_cast<std::size_t>(model.FindRegion("tendon_edge"))];
  for (const Event& pass : passes) {
    EXPECT_EQ(pass.body, "supraspinatus_tendon");
    const double bite_mm = Detail(pass, "bite_mm");
    std::printf("%s: bite %.2f mm from the torn edge, entry %s exit %s\n",
                DetailText(pass, "thread").c_str(), bite_mm, DetailText(pass, "entry_mm").c_str(),
                DetailText(pass, "exit_mm").c_str());
    EXPECT_GE(bite_mm, 10.0);
    EXPECT_LE(bite_mm, 15.0);
    // The reported bite is the geometric distance from the entry to the torn edge's nodes in
    // the frame of the pass.
    const Vec3 entry = DetailPoint(pass, "entry_mm"), exit = DetailPoint(pass, "exit_mm");
    const State at = run.Frame(pass.step);
    EXPECT_NEAR(ToRegionNodesMm(at, tendon, edge, entry), bite_mm, 0.5);
    // Through the tendon's thickness: in on the underside, out on the top, ≥ 3 mm farther from
    // the humeral head's centre (the scene origin; the tendon is 5 mm thick).
    EXPECT_GE(exit.norm() - entry.norm(), 3.0)
        << "entry " << entry.norm() << " exit " << exit.norm();
  }
}

TEST_F(SutureRepair, TheNeedleTakesTheTendonOnlyWithItsJawsClosed) {
  const Model model = io::LoadScenario(kScene);
  io::RunReader run(path_);
  const std::int64_t last = run.frame_count() - 1;
  std::vector<Event> grasps;  // the needle's (the grasper holding the edge has its own)
  for (const Event& g : OfKind(run.EventsUpTo(last), "grasp"))
    if (g.tool == "scorpion_needle") grasps.push_back(g);
  ASSERT_EQ(grasps.size(), 2u) << "one tissue grasp per bite";
  for (const Event& g : grasps) {
    const State at = run.Frame(g.step);
    EXPECT_GE(at.tools[0].jaw, model.operations.scorpion_needle.grasp_jaw) << g.detail;
  }
}

// Coming in round the tendon's anterior border, the needle's lower jaw and shaft pushed the
// whole unheld torn tendon about 10 mm posteriorly before the jaws closed on it (measured by this
// test on the script without the grasper: 9.5 mm); the grasper holding the edge keeps it within
// 2 mm from the anchor to the second pass (1.81 mm).
TEST_F(SutureRepair, TheTornEdgeStaysPutWhileTheNeedleComesIn) {
  const Model model = io::LoadScenario(kScene);
  io::RunReader run(path_);
  const std::vector<Event> events = run.EventsUpTo(run.frame_count() - 1);
  const int tendon = model.FindSoftBody("supraspinatus_tendon");
  const Region& edge = model.regions[static_cast<std::size_t>(model.FindRegion("tendon_edge"))];
  const std::vector<Event> passes = OfKind(events, "suture_pass");
  ASSERT_EQ(passes.size(), 2u);
  const Event anchor = OfKind(events, "anchor").at(0);
  const State before = run.Frame(anchor.step), after = run.Frame(passes[1].step);
  const double moved_mm =
      (Centroid(after.soft_bodies[static_cast<std::size_t>(tendon)].x, edge.nodes) -
       Centroid(before.soft_bodies[static_cast<std::size_t>(tendon)].x, edge.nodes))
          .norm();
  std::printf("torn edge centroid moved %.2f mm during the passes\n", moved_mm);
  EXPECT_LT(moved_mm, 2.0);
}

// Known defect, not yet met (docs/operations.md, "On the shoulder scene"): deepest thread node
// inside bone (signed distance to the bone surfaces, nodes in the anchor's hole excepted, every
// 5th frame), as ExpertRepair.RunIsSound measures it; run with --gtest_also_run_disabled_tests.
// The limb's middle no longer cuts through the head on the carries (4.69 mm at 12.1 s before
// thread-bone contacts held at every depth); what remains is the node the needle holds, drawn
// 4.94 mm into the head at 19.30 s (suture_b node 35) by the needle's spring, whose tool-frame
// point lies inside the bone while the jaws slide under the tendon: a tool spring outpulls the
// 20 N/mm contact (the expert's needle path does not do this).
TEST_F(SutureRepair, DISABLED_TheLimbsStayOutOfTheHumerus) {
  const Model model = io::LoadScenario(kScene);
  io::RunReader run(path_);
  double deepest = 0, when = 0;
  std::string where;
  State s;
  collision::BoneQueryWorld world;
  for (std::int64_t k = 0; k < run.frame_count(); k += 5) {
    run.ReadFrame(k, s);
    collision::SyncBoneQuery(s, &world);
    for (const ThreadState& th : s.threads) {
      for (int n = 0; n < th.x.cols(); ++n) {
        if (!th.node_alive[static_cast<std::size_t>(n)]) continue;
        bool in_hole = false;
        for (const BoneHole& h : s.holes) {
          const Vec3 d = th.x.col(n) - h.entry_mm;
          in_hole = in_hole || ((d - d.dot(h.axis) * h.axis).norm() < 0.5 * h.diameter_mm + 1.0 &&
                                d.dot(h.axis) > -1.0);
        }
        const double depth =
            in_hole ? 0.0 : -collision::PointBoneSignedDistance(th.x.col(n), &world);
        if (depth > deepest) {
          deepest = depth;
          when = s.time_s;
          where = model.threads[static_cast<std::size_t>(&th - s.threads.data())].name + " node " +
                  std::to_string(n);
        }
      }
    }
  }
  std::printf("deepest limb node in bone %.2f mm at %.2f s (%s)\n", deepest, when, where.c_str());
  EXPECT_LE(deepest, 0.5);
}

TEST_F(SutureRepair, StitchesHoldAndNothingDivergesOrOverstretches) {
  const Model model = io::LoadScenario(kScene);
  io::RunReader run(path_);
  const std::int64_t last = run.frame_count() - 1;
  double worst_strain = 0, worst_allowed = 0;
  bool finite = true;
  // The file's positions are within the writer's bound per coordinate (docs/hdf5-layout.md), so
  // a segment's length read back is within 2 sqrt(3) of it of the solver's: a segment held at
  // the 1 % strain limit can read up to that much longer.
  const io::RunWriterOptions writer;
  const double read_error_mm =
      2 * std::sqrt(3.0) * std::max(writer.position_tolerance_mm, 0.5 * writer.position_quantum_mm);
  for (std::int64_t k = 0; k <= last; k += 5) {
    const State s = run.Frame(k);
    for (std::size_t t = 0; t < s.threads.size(); ++t) {
      const Points& x = s.threads[t].x;
      const Points& x0 = model.threads[t].initial.nodes;
      finite = finite && x.allFinite();
      for (int n = 1; n < x.cols(); ++n) {
        const double rest = (x0.col(n) - x0.col(n - 1)).norm();
        const double strain = (x.col(n) - x.col(n - 1)).norm() / rest - 1;
        if (strain > worst_strain) {
          worst_strain = strain;
          worst_allowed = model.thread_solver.max_strain + read_error_mm / rest;
        }
      }
    }
    for (const SoftBodyState& b : s.soft_bodies) finite = finite && b.x.allFinite();
  }
  std::printf("worst thread strain %.4f %% as read (the limit and the file's bound: %.4f %%)\n",
              100 * worst_strain, 100 * worst_allowed);
  EXPECT_TRUE(finite);
  EXPECT_LE(worst_strain, worst_allowed);
  // At the end each limb is still stitched through the tendon (at least the paper's four nodes:
  // entry, two inside, exit) and its stitched points sit at their tissue points.
  const State end = run.Frame(last);
  for (const char* limb : {"suture_a", "suture_b"}) {
    const int t = model.FindThread(limb);
    int stitches = 0;
    double worst_mm = 0;
    for (const SpringConstraint& c : end.constraints) {
      if (c.tag != "stitch" || c.a.kind != ConstraintEnd::Kind::kThread || c.a.index != t) continue;
      ++stitches;
      worst_mm = std::max(worst_mm, (EndAt(end, c.a) - EndAt(end, c.b)).norm());
    }
    EXPECT_GE(stitches, 4) << limb;
    EXPECT_LT(worst_mm, 1.0) << limb;
  }
}

}  // namespace
}  // namespace arthrosim
