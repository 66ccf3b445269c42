// System-level verification of the soft-tissue solver: cantilever beam against an independent
// reference and beam theory, patch test, dynamics, topology changes, ARKODE, determinism.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>

#include "arthrosim/core/parallel.h"
#include "arthrosim/mesh/mesh_io.h"
#include "arthrosim/physics/fem_bench.h"
#include "arthrosim/physics/soft_system.h"

namespace arthrosim::physics {
namespace {

std::string BeamPath(const char* h) {
  return std::string(ARTHROSIM_SOURCE_DIR) + "/tests/testdata/beam/beam_" + h + ".msh";
}

double StaticTip(const std::string& path) {
  const Model model = MakeBeamModel(mesh::ReadTetMesh(path), 0, 0);
  State state = MakeInitialState(model);
  SoftSystem sys;
  sys.Build(model, state);
  sys.SolveStatic(model, &state, 1);
  return BeamTipDeflection(state);
}

// Independent reference (linear tets on the same gmsh meshes): 0.7248 / 1.2335 / 1.4008 mm.
TEST(BeamStatic, MatchesReferenceAndConvergesToBeamTheory) {
  const double ref[3] = {0.7248, 1.2335, 1.4008};
  const char* h[3] = {"5", "2.5", "1.25"};
  double prev_err = 1e9;
  for (int i = 0; i < 3; ++i) {
    const double tip = -StaticTip(BeamPath(h[i]));
    std::printf("beam h=%s: static mean tip deflection %.5f mm (reference %.4f)\n", h[i], tip,
                ref[i]);
    EXPECT_NEAR(tip, ref[i], 0.005 * ref[i]) << "mesh h = " << h[i];
    const double err = std::abs(tip - kBeamEulerBernoulliTipMm) / kBeamEulerBernoulliTipMm;
    EXPECT_LT(err, prev_err) << "error to beam theory must shrink with refinement";
    prev_err = err;
  }
  EXPECT_LT(prev_err, 0.06);
}

}  // namespace
}  // namespace arthrosim::physics
