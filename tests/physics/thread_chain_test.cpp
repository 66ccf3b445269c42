#include "arthrosim/physics/thread_chain.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>

#include "arthrosim/core/rng.h"
#include "arthrosim/core/units.h"
#include "thread_test_util.h"

namespace arthrosim::physics {
namespace {

using testing::FloorContact;
using testing::NodeSpring;
using testing::PolylineThread;
using testing::RestState;

const Vec3 kGravity(0, 0, -units::kStandardGravityMmS2);

// Catenary parameter a for a chain of length S hung between two points at the same height,
// span D: S = 2 a sinh(D / (2 a)), solved by bisection on a (S > D).
double CatenaryParameter(double S, double D) {
  double lo = 1e-3, hi = 1e6;
  for (int i = 0; i < 200; ++i) {
    const double mid = std::sqrt(lo * hi);
    if (2 * mid * std::sinh(D / (2 * mid)) > S)
      lo = mid;
    else
      hi = mid;
  }
  return std::sqrt(lo * hi);
}

TEST(ThreadChain, HangingThreadSettlesToCatenary) {
  const double span = 40, length = 60;
  const double drop = std::sqrt(0.25 * length * length - 0.25 * span * span);
  ThreadModel m = PolylineThread({{-20, 0, 0}, {0, 0, -drop}, {20, 0, 0}}, 40);  // 81 nodes
  m.fixed_nodes = {0, 80};
  m.damping_per_s = 2;
  m.max_speed_mm_s = 1000;
  std::vector<ThreadModel> models{m};
  std::vector<ThreadState> states{RestState(m)};
  ThreadWorkspace ws;
  InitThreadWorkspace(models, &ws);
  double vmax = 0;
  for (int step = 0; step < 600; ++step) {
    StepThreads(models, 0.02, kGravity, nullptr, nullptr, &states, &ws);
    vmax = 0;
    for (int i = 0; i < states[0].v.cols(); ++i) vmax = std::max(vmax, states[0].v.col(i).norm());
  }
  EXPECT_LT(vmax, 1e-3) << "not settled";
  const double a = CatenaryParameter(length, span);
  const double sag_ref = a * (std::cosh(span / (2 * a)) - 1);
  const Points& x = states[0].x;
  const double sag = -x.col(40).z();
  EXPECT_NEAR(sag, sag_ref, 0.02 * sag_ref);
  double worst = 0;
  for (int i = 0; i < x.cols(); ++i) {
    const double z_ref = a * std::cosh(x(0, i) / a) - a * std::cosh(span / (2 * a));
    worst = std::max(worst, std::abs(x(2, i) - z_ref));
    EXPECT_NEAR(x(1, i), 0, 1e-9);
  }
  EXPECT_LT(worst, 0.02 * sag_ref) << "shape differs from the catenary";
  // Inextensible: the stiff chain keeps its length.
  EXPECT_NEAR(ThreadLength(states[0]), length, 1e-4 * length);
  RecordProperty("sag_mm", std::to_string(sag));
  RecordProperty("sag_ref_mm", std::to_string(sag_ref));
  std::printf("catenary: sag %.5f mm, analytic %.5f mm, worst node error %.5f mm\n", sag, sag_ref,
              worst);
}

TEST(ThreadChain, OneNewtonPullStretchesAsEA) {
  ThreadModel m = PolylineThread({{0, 0, 0}, {50, 0, 0}}, 50);
  m.fixed_nodes = {0};
  m.damping_per_s = 5;
  std::vector<ThreadModel> models{m};
  std::vector<ThreadState> states{RestState(m)};
  ThreadWorkspace ws;
  InitThreadWorkspace(models, &ws);
  SpringSet springs{NodeSpring(0, 50, 1.0)};
  springs[0].anchor_mm = Vec3(51.0, 0, 0);  // ~1 N pull
  for (int step = 0; step < 100; ++step)
    StepThreads(models, 0.02, Vec3::Zero(), nullptr, &springs, &states, &ws);
  const double force = springs[0].force_n.x();
  EXPECT_NEAR(force, 1.0, 0.01);
  const double stretch = states[0].x(0, 50) - 50.0;
  const double expected = force * 50.0 / m.stretch_stiffness_n;
  EXPECT_NEAR(stretch, expected, 0.02 * expected);
  EXPECT_LE(stretch, 0.01 * 50.0);
  std::printf("pull %.6f N: stretch %.6e mm, F L / EA %.6e mm\n", force, stretch, expected);
}

TEST(ThreadChain, SpeedCapRespected) {
  ThreadModel m = PolylineThread({{0, 0, 0}, {20, 0, 0}}, 20);
  m.max_speed_mm_s = 100;
  std::vector<ThreadModel> models{m};
  std::vector<ThreadState> states{RestState(m)};
  ThreadWorkspace ws;
  InitThreadWorkspace(models, &ws);
  bool capped = false;
  for (int step = 0; step < 30; ++step) {
    StepThreads(models, 0.02, kGravity, nullptr, nullptr, &states, &ws);
    for (int i = 0; i < states[0].v.cols(); ++i) {
      const double sp = states[0].v.col(i).norm();
      ASSERT_LE(sp, 100.0 * (1 + 1e-12));
      if (sp > 99.999) capped = true;
    }
  }
  EXPECT_TRUE(capped) << "free fall should reach the cap";
  EXPECT_GT(ws.last.speed_capped_nodes, 0);
}

TEST(ThreadChain, FixedAndDeadNodesUntouched) {
  ThreadModel m = PolylineThread({{0, 0, 0}, {10, 0, 0}}, 10);
  m.fixed_nodes = {0};
  std::vector<ThreadModel> models{m};
  std::vector<ThreadState> states{RestState(m)};
  for (int i = 7; i <= 10; ++i) states[0].node_alive[i] = 0;
  const Points x_init = states[0].x;
  ThreadWorkspace ws;
  InitThreadWorkspace(models, &ws);
  for (int step = 0; step < 10; ++step)
    StepThreads(models, 0.02, kGravity, nullptr, nullptr, &states, &ws);
  EXPECT_EQ(states[0].x.col(0), x_init.col(0));
  for (int i = 7; i <= 10; ++i) EXPECT_EQ(states[0].x.col(i), x_init.col(i));
  EXPECT_LT(states[0].x(2, 6), -1.0);  // the alive free part fell
}

TEST(ThreadChain, PointContactHoldsThreadAbovePlane) {
  ThreadModel m = PolylineThread({{0, 0, 1}, {20, 0, 1}}, 20);
  std::vector<ThreadModel> models{m};
  std::vector<ThreadState> states{RestState(m)};
  ThreadWorkspace ws;
  InitThreadWorkspace(models, &ws);
  for (int step = 0; step < 100; ++step) {
    ContactSet contacts;
    for (int i = 0; i < 21; ++i) contacts.push_back(FloorContact(0, i, 1));
    StepThreads(models, 0.02, kGravity, &contacts, nullptr, &states, &ws);
    if (step == 99) {
      double total = 0;
      for (const PointContact& c : contacts) total += c.force_n;
      const double weight_n = 0.25 * units::kPi * 0.55 * 0.55 * 20 * 1300e-9 * 9.81;
      EXPECT_NEAR(total, weight_n, 1e-3 * weight_n);
    }
  }
  for (int i = 0; i < 21; ++i) EXPECT_GT(states[0].x(2, i), -1e-3);
}

TEST(ThreadChain, RejectsNonChain) {
  ThreadModel m = PolylineThread({{0, 0, 0}, {3, 0, 0}}, 3);
  m.initial.edges[1] = {2, 1};
  EXPECT_THROW(MakeThreadRest(m), std::invalid_argument);
  ThreadModel z = PolylineThread({{0, 0, 0}, {3, 0, 0}}, 3);
  z.initial.nodes.col(2) = z.initial.nodes.col(1);
  EXPECT_THROW(MakeThreadRest(z), std::invalid_argument);
}

TEST(ThreadChain, BendingResistsCantilever) {
  // A short cantilever clamped by its first two nodes: with EI the tip droops less than
  // without, and the small-deflection tip deflection w L^4 / (8 EI) is matched to 10 %.
  auto tip = [](double ei) {
    ThreadModel m = PolylineThread({{0, 0, 0}, {10, 0, 0}}, 40);
    m.fixed_nodes = {0, 1};
    m.bend_stiffness_n_mm2 = ei;
    m.damping_per_s = 20;
    std::vector<ThreadModel> models{m};
    std::vector<ThreadState> states{RestState(m)};
    ThreadWorkspace ws;
    InitThreadWorkspace(models, &ws);
    for (int step = 0; step < 400; ++step)
      StepThreads(models, 0.02, kGravity, nullptr, nullptr, &states, &ws);
    return -states[0].x(2, 40);
  };
  const double ei = 0.5;                                              // N mm^2
  const double w = 0.25 * units::kPi * 0.55 * 0.55 * 1300e-9 * 9810;  // mN / mm
  const double l = 10 - 0.25;  // free length beyond the clamp at node 1
  const double ref = w * std::pow(l, 4) / (8 * ei * 1e3);
  const double got = tip(ei);
  EXPECT_NEAR(got, ref, 0.1 * ref);
  EXPECT_GT(tip(0.0), 10 * got);
  std::printf("cantilever tip %.6e mm, w L^4 / 8 EI %.6e mm\n", got, ref);
}

}  // namespace
}  // namespace arthrosim::physics
