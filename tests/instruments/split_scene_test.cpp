// Split-mode scissors on the shoulder scene: scenarios/rotator_cuff_repair.yaml with the
// scissors in split mode runs the biceps tenotomy of trajectories/ops/scissors.yaml in process;
// every step is checked from the State (rest positions are not in the run file).
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <functional>
#include <numeric>
#include <sstream>
#include <stdexcept>
#include <string>

#include "arthrosim/input/script_source.h"
#include "arthrosim/instruments/cutting.h"
#include "arthrosim/io/scenario_loader.h"
#include "arthrosim/sim/step.h"
#include "arthrosim/sim/workspace.h"
#include "op_scene.h"

namespace arthrosim {
namespace {

const std::string kSource = ARTHROSIM_SOURCE_DIR;

// The shoulder scenario with `scissors: {mode: split}` added to its operations section.
Model SplitShoulder() {
  const std::string path = kSource + "/scenarios/rotator_cuff_repair.yaml";
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  std::string yaml = text.str();
  const std::string key = "\noperations:\n";
  const std::size_t at = yaml.find(key);
  if (at == std::string::npos) throw std::runtime_error("no operations section in " + path);
  yaml.insert(at + key.size(), "  scissors: {mode: split}\n");
  Model m = io::LoadScenarioFromText(yaml, path);
  if (m.operations.scissors.mode != CutMode::kSplit) throw std::runtime_error("not split mode");
  return m;
}

// Alive elements of a body whose signed volume is not positive at these positions.
int Inverted(const SoftBodyState& b, const Points& x) {
  int n = 0;
  for (std::size_t t = 0; t < b.tets.size(); ++t) {
    if (!b.tet_alive[t]) continue;
    const mesh::Tet& e = b.tets[t];
    const Vec3 a = x.col(e[0]);
    n += (x.col(e[1]) - a).dot((x.col(e[2]) - a).cross(x.col(e[3]) - a)) > 0 ? 0 : 1;
  }
  return n;
}

// Connected pieces of the alive tets (tets sharing a node connect): a label per node, -1 unused.
std::vector<int> Pieces(const SoftBodyState& b) {
  std::vector<int> root(static_cast<std::size_t>(b.x.cols()));
  std::iota(root.begin(), root.end(), 0);
  std::function<int(int)> find = [&](int i) {
    while (root[static_cast<std::size_t>(i)] != i) i = root[static_cast<std::size_t>(i)];
    return i;
  };
  std::vector<int> label(root.size(), -1);
  for (std::size_t t = 0; t < b.tets.size(); ++t) {
    if (!b.tet_alive[t]) continue;
    for (std::int32_t n : b.tets[t]) root[static_cast<std::size_t>(find(n))] = find(b.tets[t][0]);
  }
  for (std::size_t t = 0; t < b.tets.size(); ++t) {
    if (!b.tet_alive[t]) continue;
    for (std::int32_t n : b.tets[t]) label[static_cast<std::size_t>(n)] = find(n);
  }
  return label;
}

int Count(const std::vector<int>& label) {
  int c = 0;
  for (std::size_t i = 0; i < label.size(); ++i) c += label[i] == static_cast<int>(i);
  return c;
}

// The biceps tenotomy in split mode: the tendon ends in two pieces, one per fixed end, its rest
// volume conserved to 1e-9 at every step, no element of any soft body inverted (at rest or in
// the current configuration) at any step, every new piece of radius ratio >= 0.03 at rest.
TEST(SplitScene, BicepsTenotomyInSplitModeGivesTwoPiecesConservingVolume) {
  const Model m = SplitShoulder();
  ASSERT_EQ(m.operations.scissors.mode, CutMode::kSplit);
  const int biceps = m.FindSoftBody("biceps_tendon");
  ASSERT_GE(biceps, 0);
  input::ScriptOptions o;
  o.dt_s = m.options.dt_s;
  auto script = input::ScriptSource::Open(kSource + "/trajectories/ops/scissors.yaml", m, o);
  State s = MakeInitialState(m);
  sim::Workspace ws;
  sim::BuildWorkspace(m, s, &ws);
  const SoftBodyState& b = s.soft_bodies[static_cast<std::size_t>(biceps)];
  const double v0 = testing::AliveRestVolume(s, biceps);
  const std::size_t tets0 = b.tets.size();
  ASSERT_EQ(Count(Pieces(b)), 1);
  const int steps = static_cast<int>(script->end_time_s() / m.options.dt_s + 0.5);
  int cuts = 0, split_tets = 0;
  for (int k = 0; k < steps; ++k) {
    InputFrame f;
    script->Frame(k, k * m.options.dt_s, &f);
    sim::Step(m, f, &s, &ws);
    FeedbackFrame fb;
    for (std::size_t i = 0; i < s.tools.size() && i < fb.force_n.size(); ++i)
      fb.force_n[i] = s.tools[i].force_n;
    script->Feedback(fb);
    for (const Event& e : s.events) {
      if (e.kind != "cut") continue;
      EXPECT_EQ(e.body, "biceps_tendon");
      EXPECT_NE(e.detail.find("mode=split"), std::string::npos) << e.detail;
      ++cuts;
      split_tets += std::atoi(e.detail.c_str() + e.detail.find("tets=") + 5);
    }
    for (const SoftBodyState& sb : s.soft_bodies) {
      ASSERT_TRUE(sb.x.allFinite()) << "step " << k;
      ASSERT_EQ(Inverted(sb, sb.x), 0) << "step " << k;
      ASSERT_EQ(Inverted(sb, sb.x_rest), 0) << "step " << k;
    }
    ASSERT_NEAR(testing::AliveRestVolume(s, biceps), v0, 1e-9 * v0) << "step " << k;
  }
  EXPECT_EQ(b.removed_volume_mm3, 0);
  double worst = 1;
  for (std::size_t t = tets0; t < b.tets.size(); ++t) {
    if (!b.tet_alive[t]) continue;
    const mesh::Tet& e = b.tets[t];
    worst = std::min(worst, instruments::RadiusRatio(b.x_rest.col(e[0]), b.x_rest.col(e[1]),
                                                     b.x_rest.col(e[2]), b.x_rest.col(e[3])));
  }
  const std::vector<int> label = Pieces(b);
  std::printf(
      "split tenotomy: %d cut events, %d tets split, %zu -> %zu tets, %d pieces, worst "
      "radius ratio of a piece %.4f\n",
      cuts, split_tets, tets0, b.tets.size(), Count(label), worst);
  EXPECT_GE(worst, 0.03);
  EXPECT_GE(cuts, 1);
  ASSERT_EQ(Count(label), 2);
  // Each piece holds exactly one fixed end: the stumps hang from their ends.
  std::vector<int> piece_of_end;
  for (const char* end : {"biceps_ends_proximal", "biceps_ends_distal"}) {
    const int r = m.FindRegion(end);
    ASSERT_GE(r, 0) << end;
    std::vector<int> pieces;
    for (std::int32_t n : m.regions[static_cast<std::size_t>(r)].nodes)
      pieces.push_back(label[static_cast<std::size_t>(n)]);
    std::sort(pieces.begin(), pieces.end());
    pieces.erase(std::unique(pieces.begin(), pieces.end()), pieces.end());
    ASSERT_EQ(pieces.size(), 1u) << end;
    piece_of_end.push_back(pieces[0]);
  }
  EXPECT_NE(piece_of_end[0], piece_of_end[1]);
}

}  // namespace
}  // namespace arthrosim
