#pragma once
// Appends primitive shapes (cylinders, spheres, cones, tori, boxes, tubes) to a SceneMesh. Shapes
// are given in a local frame and placed in the world by `frame`.
#include <Eigen/Geometry>
#include <vector>

#include "arthrosim/core/types.h"
#include "arthrosim/render/scene.h"

namespace arthrosim::render {

class MeshBuilder {
 public:
  /// Appends to `mesh` (not owned); local coordinates are mapped by `frame` (mm).
  MeshBuilder(SceneMesh* mesh, const Eigen::Isometry3d& frame) : mesh_(mesh), frame_(frame) {}

  void set_frame(const Eigen::Isometry3d& frame) { frame_ = frame; }

  /// Frustum from p0 (radius r0) to p1 (radius r1), `sides` facets, optional end discs.
  void Cylinder(const Vec3& p0, const Vec3& p1, double r0, double r1, int sides, bool cap0,
                bool cap1);
  /// Open cylinder from z0 to z1 along local z with radius r, leaving out facets whose angle
  /// (from +x, about +z) is within `gap_half_angle` of `gap_center` and z inside [gz0, gz1].
  void CylinderWithWindow(double z0, double z1, double r, int sides, int rings, double gap_center,
                          double gap_half_angle, double gz0, double gz1);
  /// Flat triangle (a, b, c), counter-clockwise seen from its front (normal (b-a)x(c-a)).
  void Triangle(const Vec3& a, const Vec3& b, const Vec3& c);
  /// UV sphere (or ellipsoid with `scale`) centred at c.
  void Sphere(const Vec3& c, const Vec3& radii, int stacks, int slices);
  /// Torus in the plane orthogonal to `axis` through c.
  void Torus(const Vec3& c, const Vec3& axis, double major, double minor, int major_segments,
             int minor_segments);
  /// Box with half extents `half` in a local frame `box_frame` (flat-shaded faces).
  void Box(const Eigen::Isometry3d& box_frame, const Vec3& half);
  /// Tapered blade: box from z = 0 to z = length in box_frame, width and thickness shrinking
  /// linearly to `tip_scale` at the far end.
  void Blade(const Eigen::Isometry3d& box_frame, double length, double width, double thickness,
             double tip_scale);
  /// Tube of radius r along a polyline (world points: frame not applied), parallel-transport
  /// frames; uv = (arc length / (2 r), angle / 2pi).
  void Tube(const std::vector<Vec3>& points, double r, int sides);

 private:
  std::uint32_t Add(const Vec3& local_pos, const Vec3& local_normal, float u = 0, float v = 0);
  std::uint32_t AddWorld(const Vec3& pos, const Vec3& normal, float u, float v);
  void Tri(std::uint32_t a, std::uint32_t b, std::uint32_t c);

  SceneMesh* mesh_;
  Eigen::Isometry3d frame_;
};

/// Recomputes per-vertex normals of `mesh` as area-weighted sums of its triangle normals
/// (vertices of no triangle get +z).
void ComputeVertexNormals(SceneMesh* mesh);

}  // namespace arthrosim::render
