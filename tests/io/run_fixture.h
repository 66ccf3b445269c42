#pragma once
// A small synthetic run, defined frame by frame by closed formulas (tests/io/check_run.py
// repeats them): two soft bodies (a 10 mm cube of 5 tets that loses a tet at frame 3 and splits
// tet 0 into 4 at frame 6, plus a static single tet), a 6-node thread cut at node 3 from frame 5,
// a tetrahedral bone surface that moves a vertex at frame 4 and splits an edge at frame 7, three
// instruments (grasper in slot 0 from frame 2, burr in slot 1 for frames 4..7, scissors never),
// constraints and events.
#include <string>

#include "arthrosim/core/model.h"
#include "arthrosim/core/state.h"

namespace arthrosim::io::testing {

/// The synthetic Model (dt 0.01 s, flush every 0.1 s of simulated time).
Model MakeModel();
/// Frame f (step 2f, time 0.02 f s); velocities and rest positions are left empty (3 x 0), as
/// RunReader returns them, so that BitwiseEqual compares everything that is stored.
State MakeFrame(const Model& model, int f);

/// The default bound of stored positions: RunWriterOptions' position_tolerance_mm (it exceeds
/// half the quantum).
inline constexpr double kPositionBoundMm = 0.005;
/// Largest per-coordinate difference between the soft-body and thread positions of a and b
/// (infinity if their shapes differ).
double MaxPositionError(const State& a, const State& b);
/// True when `got` (read from a run file) equals `want` bit for bit except that soft-body and
/// thread positions may differ by at most `bound_mm` per coordinate.
bool EqualWithinPositionBound(const State& got, const State& want,
                              double bound_mm = kPositionBoundMm);

/// Directory for a test's files (created empty) below the build directory.
std::string TestDir(const std::string& name);
/// Runs tests/io/<script> with the Python that has h5py; returns the exit status (0 = ok).
int RunPython(const std::string& script, const std::string& args);
/// Whether a Python with h5py is available.
bool HavePythonH5py();

}  // namespace arthrosim::io::testing
