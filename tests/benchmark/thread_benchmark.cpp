// Suture thread step benchmarks: one 60-node thread (No. 2 FiberWire defaults, EI 0.5 N mm^2)
// at dt = 20 ms with self-collision on, (a) swung by a grasping tool on a circle and (b) lying
// on the floor (PointContacts) folded in a zig-zag of 10 legs 0.6 mm apart, so that many segment
// pairs are in contact. Counters: Newton iterations, solves, segment contacts per step.
#include <benchmark/benchmark.h>

#include <cmath>
#include <vector>

#include "../physics/thread_test_util.h"
#include "arthrosim/core/units.h"
#include "arthrosim/physics/thread_chain.h"

namespace arthrosim::physics {
namespace {

ThreadModel MakeThread(const std::vector<Vec3>& pts) {
  ThreadModel m;
  m.name = "suture";
  m.initial.nodes.resize(3, static_cast<Eigen::Index>(pts.size()));
  for (std::size_t i = 0; i < pts.size(); ++i) {
    m.initial.nodes.col(static_cast<Eigen::Index>(i)) = pts[i];
    if (i + 1 < pts.size())
      m.initial.edges.push_back({static_cast<std::int32_t>(i), static_cast<std::int32_t>(i + 1)});
  }
  m.bend_stiffness_n_mm2 = 0.5;
  m.damping_per_s = 1;
  m.fixed_nodes = {0};
  return m;
}

void Run(benchmark::State& bs, const ThreadModel& model, bool swing) {
  std::vector<ThreadModel> models{model};
  std::vector<ThreadState> states{testing::RestState(model)};
  ContactSet floor;
  if (!swing) {
    for (int i = 0; i < 60; ++i) floor.push_back(testing::FloorContact(0, i, 10));
  }
  ThreadWorkspace ws;
  InitThreadWorkspace(models, &ws);
  SpringSet springs{testing::NodeSpring(0, 59, swing ? 5 : 0)};
  const Vec3 end = model.initial.nodes.col(59);
  const Vec3 gravity(0, 0, -units::kStandardGravityMmS2);
  long step = 0;
  double newton = 0, solves = 0, contacts = 0;
  for (auto _ : bs) {
    const double phase = 2 * units::kPi * step * 0.02;  // 1 Hz circle of radius 8 mm
    springs[0].anchor_mm = end + Vec3(8 * std::cos(phase) - 8, 8 * std::sin(phase), 0);
    StepThreads(models, 0.02, gravity, swing ? nullptr : &floor, &springs, &states, &ws);
    newton += ws.last.newton_iterations;
    solves += ws.last.solves;
    contacts += ws.last.contact_pairs;
    ++step;
  }
  bs.counters["newton_per_step"] = newton / static_cast<double>(step);
  bs.counters["solves_per_step"] = solves / static_cast<double>(step);
  bs.counters["contacts_per_step"] = contacts / static_cast<double>(step);
}

void BM_Thread60Swing(benchmark::State& bs) {
  std::vector<Vec3> pts;
  for (int i = 0; i < 60; ++i) pts.emplace_back(0.75 * i, 0, 0);  // 44 mm
  Run(bs, MakeThread(pts), true);
}
BENCHMARK(BM_Thread60Swing)->Unit(benchmark::kMillisecond);

void BM_Thread60Folded(benchmark::State& bs) {
  std::vector<Vec3> pts;
  for (int i = 0; i < 60; ++i) {
    const int leg = i / 6, k = i % 6;
    const double y = (leg % 2 == 0) ? 0.75 * k : 0.75 * (5 - k);
    pts.emplace_back(0.6 * leg + 0.1 * (k == 5 ? 1 : 0), y, 0.3);
  }
  ThreadModel m = MakeThread(pts);
  m.fixed_nodes = {};
  m.bend_stiffness_n_mm2 = 0;  // a pliable braid: the hairpins stay folded
  Run(bs, m, false);
}
BENCHMARK(BM_Thread60Folded)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace arthrosim::physics

BENCHMARK_MAIN();
