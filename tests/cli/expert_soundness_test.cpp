// The expert repair's soundness, from its run file (expert_run.h): finite everywhere, no soft
// tissue or instrument part driven into bone, threads not stretched; and the known defects of
// threads in bone (disabled tests naming them).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <set>
#include <string>
#include <vector>

#include "arthrosim/collision/instrument_shape.h"
#include "arthrosim/collision/tool_bone_query.h"
#include "expert_run.h"
#include "run_state_util.h"

namespace arthrosim {
namespace {

using namespace expert;  // NOLINT(google-build-using-namespace): the run and its helpers
using testing::ComponentOf;

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
    // threads up to the first tail cut (after it: CutSutureStubsStayOutOfBone below)
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

// While the scorpion needle carries a limb from its loading point below the anchor round the head
// to the bite, the limb wraps round the head: thread nodes (those in the anchor's hole excepted),
// up to the first tail cut, stay within 0.5 mm of bone. Until thread-bone contacts held at every
// depth (contact.thread_bone_*), the limb's middle nodes cut through the head on a chord
// (suture_a node 19 14.3 mm deep at 70 s): fails so with them reverted.
TEST(ExpertRepair, TheLimbsStayOutOfTheHumerus) { EXPECT_LE(Survey().deepest_thread, kTunnelMm); }

// After the cutter has cut a limb, the stub left on the anchor stays out of the humerus. Until
// thread-bone contacts held at every depth, it sank in (suture_a: node 4 2.5 mm deep 2 s after
// the cut, node 11 10 mm deep 20 s later; 14.7 mm with them reverted).
TEST(ExpertRepair, CutSutureStubsStayOutOfBone) {
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

// Known defect (issue #14, docs/operations.md (4) trial (l)): the thread solve stalls from the
// anchor on, so the tail a pass lays straight up from the exit stays standing in the air. Each
// tail's free end should fall under gravity in the second after its pass (a 40 mm chain swinging
// about its exit falls tens of millimetres in that time; 5 mm is asked). Today: suture_a 0.071 mm,
// suture_b 0.016 mm. Enable when the thread solve converges on slack limbs.
TEST(ExpertRepair, DISABLED_ATailLeftStandingAfterAPassFallsUnderGravity) {
  int passes = 0;
  for (const Event& e : Events()) {
    if (e.kind != "suture_pass") continue;
    ++passes;
    const int t = Shoulder().FindThread(DetailText(e, "thread"));
    ASSERT_GE(t, 0);
    auto end_z = [&](double at_s) {
      const State frame = FrameAt(at_s);
      const std::vector<Vec3> limb = LimbFrom(frame.threads[static_cast<std::size_t>(t)], 0);
      return limb.back().z();
    };
    const double fall_mm = end_z(e.time_s + 0.2) - end_z(e.time_s + 1.2);
    std::printf("%s: tail end fell %.3f mm in the second after its pass\n",
                DetailText(e, "thread").c_str(), fall_mm);
    EXPECT_GE(fall_mm, 5.0);
  }
  EXPECT_EQ(passes, 2);
}

}  // namespace
}  // namespace arthrosim
