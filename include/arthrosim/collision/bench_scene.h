#pragma once
// Timing of the collision stage on a full scene, for `arthrosim bench` and Google Benchmark.
// Time is measured here only; it never influences a simulation result.
#include <cstdint>
#include <functional>
#include <string>

#include "arthrosim/collision/contact_generation.h"
#include "arthrosim/core/mesh_types.h"
#include "arthrosim/core/model.h"

namespace arthrosim::collision {

/// A box [lo, hi] cut into nx*ny*nz cubes of 6 positively oriented tets each (mm).
mesh::TetMesh BoxTets(const Vec3& lo, const Vec3& hi, int nx, int ny, int nz);
/// A closed outward ellipsoid surface: nu segments around z, nv rings pole to pole
/// (2 * nu * (nv - 1) triangles), mm.
mesh::TriMesh Ellipsoid(const Vec3& center, const Vec3& radii, int nu, int nv);

/// A synthetic scene with the sizes of the rotator-cuff scenario: two soft blocks (3 384 tets),
/// a humeral head (6 000 triangles), an acromion (132), two 60-node threads lying on the cuff,
/// a grasper and a shaver (slots 0 and 1). mm.
Model MakeBenchmarkModel();

/// Collision stage figures over a run.
struct CollisionBenchResult {
  /// Median time of Detect per step, ms: the calling thread's CPU time with one thread (not
  /// disturbed by other processes), wall time with more (ThreadCount() > 1).
  double median_ms = 0;
  double p90_ms = 0;          ///< 90th percentile, ms
  double mean_contacts = 0;   ///< contacts per step
  std::int64_t rebuilds = 0;  ///< tree builds (first step + topology changes)
  int threads = 1;            ///< ThreadCount() during the run
};

/// Runs `steps` collision stages on `model` (any scenario; made for scenarios/bench_full.yaml):
/// thread 0 is laid along x on the top surface of the tendon (the soft body named "*tendon*",
/// else body 0), a grasper (slot 0) and a shaver (slot 1) (else instruments 0 and 1), coming from
/// above tilted 30 degrees toward their portals, press 0.5 mm into that surface and cross the
/// thread along y at 100 mm/s (dt = 20 ms), the soft bodies carry a 0.3 mm travelling wave.
/// Deterministic workload. `on_step`, if set, sees each step's output (outside the timing), e.g.
/// to dump the contacts and check that a speed change leaves them unchanged.
CollisionBenchResult BenchmarkCollision(
    const Model& model, int steps,
    const std::function<void(int step, const CollisionOutput& out)>& on_step = {});

/// The figures as `key=value` lines for `arthrosim bench`, the first one
/// `collision_ms_median=<ms>`.
std::string FormatCollisionBench(const CollisionBenchResult& r);

}  // namespace arthrosim::collision
