#pragma once
// A synthetic shoulder-sized scene for render benchmarks and tests when no anatomy scenario is
// available: a humeral head and an acromion (bone spheres/ellipsoids), a tendon slab of tets over
// the head, a suture thread, a grasper and the scope looking at the tendon.
#include "arthrosim/core/model.h"
#include "arthrosim/core/state.h"

namespace arthrosim::render {

/// Size knobs of the synthetic scene.
struct SyntheticSceneSize {
  int bone_subdivisions = 28;  ///< UV-sphere rings per bone (4 n (n - 1) triangles per bone)
  int tendon_cells_x = 22;     ///< hexahedral cells (5 tets each) of the tendon slab
  int tendon_cells_y = 15;
  int tendon_cells_z = 2;
};

/// A closed UV ellipsoid around `centre` with semi-axes `radii` (mm), triangles facing out: two
/// poles and n - 1 rings of 2n vertices.
mesh::TriMesh UvEllipsoid(const Vec3& centre, const Vec3& radii, int n);

/// Fills `model` and returns its initial State with tools inserted (slot 0 grasper).
/// Default size: ~6 000 bone triangles and 3 300 tets.
State MakeSyntheticScene(const SyntheticSceneSize& size, Model* model);

}  // namespace arthrosim::render
