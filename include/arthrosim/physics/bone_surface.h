#pragma once
// Bone reshaping by burr and awl on the closed triangle surface.
//
// Representation: the bone stays a closed, outward-oriented triangle surface (BoneState::surface).
// Why: a closed orientable surface gives the enclosed volume exactly by the divergence theorem
// (sum of signed tetrahedra from the origin), so the removed volume is exact bookkeeping, not an
// estimate; the renderer and collision already consume triangles; and the two operations below
// keep it closed by construction: vertices only move (connectivity unchanged) and an edge split
// replaces the two triangles sharing the edge by four (every edge still has exactly two
// triangles, with opposite orientation). A voxel/level-set model would need remeshing for
// rendering and would report volume only to the voxel size.
//
// A call (1) splits, longest first, every edge near the tool longer than max_edge_mm (so the
// carved shape resolves the tool), (2) moves the vertices inside the tool onto its surface,
// limited to max_depth per call, (3) reverts any vertex whose move would flip an incident
// triangle (vertices never pass through each other locally), and repeats (1)-(3) a few rounds so
// chord midpoints left inside the tool are carved too. It returns V_before - V_after.
#include "arthrosim/core/mesh_types.h"
#include "arthrosim/core/state.h"

namespace arthrosim::physics {

/// Enclosed volume of a closed outward-oriented surface, mm^3 (divergence theorem).
double EnclosedVolume(const mesh::TriMesh& surface);

/// Result of a watertightness check.
struct WatertightReport {
  int boundary_edges = 0;     ///< directed edges without an opposite twin
  int nonmanifold_edges = 0;  ///< directed edges used more than once (or shared by > 2 triangles)
  int degenerate_tris = 0;    ///< triangles with a repeated vertex or an index out of range
  bool ok() const { return boundary_edges == 0 && nonmanifold_edges == 0 && degenerate_tris == 0; }
};

/// Every edge shared by exactly two triangles with opposite orientation, no degenerate triangle.
WatertightReport CheckWatertight(const mesh::TriMesh& surface);

/// Options shared by the bone operations.
struct BoneCarveOptions {
  double max_edge_mm = 0.5;  ///< edges near the tool are split until no longer than this
  int rounds = 4;            ///< split/move rounds per call
};

/// Burr pass: moves surface vertices inside the sphere (center, radius; mm) radially onto its
/// surface, each by at most max_depth_mm. Updates removed_volume_mm3; returns the volume removed
/// by this call, mm^3 (>= 0 up to rounding when the sphere only removes material).
double CarveSphere(BoneState* bone, const Vec3& center, double radius_mm, double max_depth_mm,
                   const BoneCarveOptions& options = {});

/// Smooths the rim of a crater: every vertex at distance in [inner_mm, outer_mm] from `center`
/// moves toward the mean of its neighbours, only inward (material is never added) and only if
/// no incident triangle flips, `iterations` times. Removes the step edge a carve leaves where
/// the tool sphere meets the untouched surface. Returns the volume removed, mm^3 (>= 0 up to
/// rounding); updates removed_volume_mm3 and revision.
double SmoothRim(BoneState* bone, const Vec3& center, double inner_mm, double outer_mm,
                 int iterations = 2);

/// Awl push: the tip at `tip` pointing along unit `axis` (into the bone) displaces surface
/// vertices at distance rho < radius from the axis and axial coordinate s in [-radius, f(rho))
/// to s = f(rho) = depth (1 - (rho / radius)^2): a concave hole deepest on the axis. Returns the
/// volume removed by this call, mm^3; updates removed_volume_mm3.
double PushAlong(BoneState* bone, const Vec3& tip, const Vec3& axis, double radius_mm,
                 double depth_mm, const BoneCarveOptions& options = {});

}  // namespace arthrosim::physics
