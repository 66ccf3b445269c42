#include "cull.h"

#include <cmath>

namespace arthrosim::render {
namespace {

Vec3 Pos(const Vertex& v) { return Vec3(v.pos[0], v.pos[1], v.pos[2]); }

// Ray/triangle crossing: 1 hit, 0 miss, -1 too close to an edge, a vertex or the ray origin
// to decide reliably (Moller-Trumbore with margins).
int Crossing(const Vec3& o, const Vec3& d, const Vec3& a, const Vec3& b, const Vec3& c) {
  constexpr double kEps = 1e-7;
  const Vec3 e1 = b - a, e2 = c - a;
  const Vec3 p = d.cross(e2);
  const double det = e1.dot(p);
  const double scale = e1.norm() * e2.norm();
  if (std::abs(det) <= kEps * scale) {
    // ray parallel to the plane: no crossing unless it lies in it
    const Vec3 n = e1.cross(e2);
    return std::abs(n.dot(o - a)) <= kEps * scale * (o - a).norm() ? -1 : 0;
  }
  const double inv = 1.0 / det;
  const Vec3 s = o - a;
  const double u = s.dot(p) * inv;
  if (u < -kEps || u > 1 + kEps) return 0;
  const Vec3 q = s.cross(e1);
  const double v = d.dot(q) * inv;
  if (v < -kEps || u + v > 1 + kEps) return 0;
  const double t = e2.dot(q) * inv;
  if (t < -kEps) return 0;
  if (u <= kEps || v <= kEps || u + v >= 1 - kEps || t <= kEps) return -1;
  return 1;
}

}  // namespace

bool BackFacesHidden(const SceneMesh& mesh, const Vec3& eye, double reach) {
  if (!mesh.closed) return false;
  // an irrational-ish fixed direction makes exact edge hits unlikely (and they answer false)
  const Vec3 dir = Vec3(0.5366, 0.7071, 0.4608).normalized();
  int crossings = 0;
  for (std::size_t t = 0; t + 2 < mesh.indices.size(); t += 3) {
    const Vec3 a = Pos(mesh.vertices[mesh.indices[t]]), b = Pos(mesh.vertices[mesh.indices[t + 1]]),
               c = Pos(mesh.vertices[mesh.indices[t + 2]]);
    // triangle box within reach of the eye: the near plane might cut this mesh
    const Vec3 lo = a.cwiseMin(b).cwiseMin(c), hi = a.cwiseMax(b).cwiseMax(c);
    if ((eye.array() > lo.array() - reach).all() && (eye.array() < hi.array() + reach).all()) {
      return false;
    }
    const int hit = Crossing(eye, dir, a, b, c);
    if (hit < 0) return false;
    crossings += hit;
  }
  return crossings % 2 == 0;
}

Eigen::AlignedBox3d MeshBox(const SceneMesh& mesh) {
  Eigen::AlignedBox3d box;
  for (const Vertex& v : mesh.vertices) box.extend(Pos(v));
  return box;
}

bool CullBackFaces(const SceneMesh& mesh, const Eigen::AlignedBox3d& box, const Vec3& eye,
                   double reach) {
  return mesh.closed && (box.exteriorDistance(eye) > reach || BackFacesHidden(mesh, eye, reach));
}

}  // namespace arthrosim::render
