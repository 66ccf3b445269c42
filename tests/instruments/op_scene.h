#pragma once
// Small scenes for the operation tests: the small test scenario with its soft body replaced by a
// grid of unit cubes (6 tets each) and the instruments the tests need, and helpers to run steps
// with a tool held by slot 0.
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "arthrosim/core/model.h"
#include "arthrosim/core/state.h"
#include "arthrosim/sim/step.h"
#include "arthrosim/sim/workspace.h"

namespace arthrosim::testing {

/// A run of `model` from its initial State: the State and the Workspace built for it (bind them
/// as `auto& [s, ws] = run;`).
struct SceneRun {
  explicit SceneRun(const Model& model) : s(MakeInitialState(model)) {
    sim::BuildWorkspace(model, s, &ws);
  }
  State s;
  sim::Workspace ws;
};

/// The quality every piece of a split keeps with the default snap_fraction 0.2 (radius ratio;
/// the grids' Kuhn tets have 0.72). Measured worst over the 300 random planes of
/// ScissorsSplit.RandomPlanesGiveValidSeparatedPiecesOfBoundedQuality: 0.039.
inline constexpr double kMinSplitQuality = 0.03;

/// A box [lo, lo + n * cell] of n.x * n.y * n.z cubes of edge `cell` mm, 6 positive tets each.
mesh::TetMesh GridMesh(const Vec3& lo, const std::array<int, 3>& n, double cell);

/// The small scenario (tests/testdata/scenes/small.yaml) with soft body 0 replaced by `mesh`,
/// its fixed nodes those for which fixed(position) is true, no regions or landmarks, and
/// instruments scissors, cutter, shaver, electrocautery and grasper (slot-ready, default sizes).
Model GridModel(const mesh::TetMesh& mesh, const std::function<bool(const Vec3&)>& fixed);

/// A tool command of slot 0 holding instrument `name` at `position` with the tool axes given as
/// world vectors (x = jaw opening direction, z = forward), jaw and buttons.
InputFrame ToolInput(const Model& m, const std::string& name, const Vec3& position,
                     const Vec3& tool_x, const Vec3& tool_z, double jaw, int buttons);

/// Connected components of the alive tets of soft body `body` (tets sharing a node connect).
int AliveComponents(const State& s, int body);

/// Sum of rest volumes of the alive tets of a body, mm^3.
double AliveRestVolume(const State& s, int body);

/// Events of a kind in the state (this step's).
std::vector<Event> EventsOf(const State& s, const std::string& kind);

/// The integer value of `key=` in an event detail (-1 if absent).
long long DetailInt(const std::string& detail, const std::string& key);
/// The number value of `key=` in an event detail (NaN if absent).
double DetailNumber(const std::string& detail, const std::string& key);

}  // namespace arthrosim::testing
