#pragma once
// Timing of the collision stage on a full scene, for `arthrosim bench` and Google Benchmark.
// Wall-clock time is measured here only; it never influences a simulation result.
#include <cstdint>

#include "arthrosim/core/model.h"
#include "arthrosim/mesh/tet_mesh.h"

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
  double median_ms = 0;       ///< median wall time of Detect per step, ms
  double p90_ms = 0;          ///< 90th percentile, ms
  double mean_contacts = 0;   ///< contacts per step
  std::int64_t rebuilds = 0;  ///< tree builds (first step + topology changes)
};

/// Runs `steps` collision stages on `model` (any scenario: tools with instruments 0 and 1 are
/// inserted, moved at 100 mm/s with dt = 20 ms through the scene's bounding box, soft bodies
/// are deformed by a small travelling wave) and returns the timing. Deterministic workload.
CollisionBenchResult BenchmarkCollision(const Model& model, int steps);

}  // namespace arthrosim::collision
