#include "mesh_builder.h"

#include <cmath>
#include <numbers>

namespace arthrosim::render {
namespace {

constexpr double kPi = std::numbers::pi;

// Any unit vector orthogonal to unit n (deterministic choice).
Vec3 AnyOrthogonal(const Vec3& n) {
  const Vec3 a = std::abs(n.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitY();
  return n.cross(a).normalized();
}

}  // namespace

std::uint32_t MeshBuilder::AddWorld(const Vec3& pos, const Vec3& normal, float u, float v) {
  Vertex vx{};
  for (int i = 0; i < 3; ++i) {
    vx.pos[i] = static_cast<float>(pos[i]);
    vx.normal[i] = static_cast<float>(normal[i]);
    vx.tex[i] = vx.pos[i];
  }
  vx.uv[0] = u;
  vx.uv[1] = v;
  vx.rough = 0;
  mesh_->vertices.push_back(vx);
  return static_cast<std::uint32_t>(mesh_->vertices.size() - 1);
}

std::uint32_t MeshBuilder::Add(const Vec3& local_pos, const Vec3& local_normal, float u, float v) {
  return AddWorld(frame_ * local_pos, frame_.linear() * local_normal, u, v);
}

void MeshBuilder::Tri(std::uint32_t a, std::uint32_t b, std::uint32_t c) {
  mesh_->indices.insert(mesh_->indices.end(), {a, b, c});
}

void MeshBuilder::Triangle(const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 n = (b - a).cross(c - a).normalized();
  const std::uint32_t i = Add(a, n), j = Add(b, n), k = Add(c, n);
  Tri(i, j, k);
}

void MeshBuilder::Cylinder(const Vec3& p0, const Vec3& p1, double r0, double r1, int sides,
                           bool cap0, bool cap1) {
  const Vec3 axis = (p1 - p0).normalized();
  const double len = (p1 - p0).norm();
  const Vec3 e1 = AnyOrthogonal(axis);
  const Vec3 e2 = axis.cross(e1);
  // side normals lean by the taper angle
  const double slope = (r0 - r1) / len;
  const std::uint32_t base = static_cast<std::uint32_t>(mesh_->vertices.size());
  for (int i = 0; i <= sides; ++i) {
    const double a = 2 * kPi * i / sides;
    const Vec3 radial = std::cos(a) * e1 + std::sin(a) * e2;
    const Vec3 n = (radial + slope * axis).normalized();
    Add(p0 + r0 * radial, n, 0, static_cast<float>(i) / sides);
    Add(p1 + r1 * radial, n, static_cast<float>(len), static_cast<float>(i) / sides);
  }
  for (int i = 0; i < sides; ++i) {
    const std::uint32_t a = base + 2 * i, b = a + 1, c = a + 2, d = a + 3;
    Tri(a, c, b);
    Tri(b, c, d);
  }
  // end discs, flat
  for (int end = 0; end < 2; ++end) {
    if ((end == 0 && !cap0) || (end == 1 && !cap1)) continue;
    const Vec3 c = end == 0 ? p0 : p1;
    const double r = end == 0 ? r0 : r1;
    if (r <= 0) continue;
    const Vec3 n = end == 0 ? Vec3(-axis) : axis;
    const std::uint32_t center = Add(c, n);
    const std::uint32_t ring = static_cast<std::uint32_t>(mesh_->vertices.size());
    for (int i = 0; i < sides; ++i) {
      const double a = 2 * kPi * i / sides;
      Add(c + r * (std::cos(a) * e1 + std::sin(a) * e2), n);
    }
    for (int i = 0; i < sides; ++i) {
      const std::uint32_t a = ring + i, b = ring + (i + 1) % sides;
      if (end == 0)
        Tri(center, b, a);
      else
        Tri(center, a, b);
    }
  }
}

void MeshBuilder::CylinderWithWindow(double z0, double z1, double r, int sides, int rings,
                                     double gap_center, double gap_half_angle, double gz0,
                                     double gz1) {
  for (int j = 0; j < rings; ++j) {
    const double za = z0 + (z1 - z0) * j / rings, zb = z0 + (z1 - z0) * (j + 1) / rings;
    const double zm = 0.5 * (za + zb);
    for (int i = 0; i < sides; ++i) {
      const double a0 = 2 * kPi * i / sides, a1 = 2 * kPi * (i + 1) / sides;
      double am = 0.5 * (a0 + a1) - gap_center;
      am = std::remainder(am, 2 * kPi);
      if (std::abs(am) < gap_half_angle && zm > gz0 && zm < gz1) continue;
      const Vec3 n0(std::cos(a0), std::sin(a0), 0), n1(std::cos(a1), std::sin(a1), 0);
      const std::uint32_t a = Add(Vec3(r * n0.x(), r * n0.y(), za), n0);
      const std::uint32_t b = Add(Vec3(r * n0.x(), r * n0.y(), zb), n0);
      const std::uint32_t c = Add(Vec3(r * n1.x(), r * n1.y(), za), n1);
      const std::uint32_t d = Add(Vec3(r * n1.x(), r * n1.y(), zb), n1);
      Tri(a, c, b);
      Tri(b, c, d);
    }
  }
}

void MeshBuilder::Sphere(const Vec3& c, const Vec3& radii, int stacks, int slices) {
  const std::uint32_t base = static_cast<std::uint32_t>(mesh_->vertices.size());
  for (int j = 0; j <= stacks; ++j) {
    const double phi = kPi * j / stacks;  // from +z down
    for (int i = 0; i <= slices; ++i) {
      const double th = 2 * kPi * i / slices;
      const Vec3 u(std::sin(phi) * std::cos(th), std::sin(phi) * std::sin(th), std::cos(phi));
      const Vec3 p = c + radii.cwiseProduct(u);
      const Vec3 n = u.cwiseQuotient(radii).normalized();
      Add(p, n, static_cast<float>(i) / slices, static_cast<float>(j) / stacks);
    }
  }
  const std::uint32_t row = slices + 1;
  for (int j = 0; j < stacks; ++j) {
    for (int i = 0; i < slices; ++i) {
      const std::uint32_t a = base + j * row + i, b = a + 1, c2 = a + row, d = c2 + 1;
      if (j > 0) Tri(a, c2, b);
      if (j < stacks - 1) Tri(b, c2, d);
    }
  }
}

void MeshBuilder::Torus(const Vec3& c, const Vec3& axis, double major, double minor,
                        int major_segments, int minor_segments) {
  const Vec3 n = axis.normalized();
  const Vec3 e1 = AnyOrthogonal(n), e2 = n.cross(e1);
  const std::uint32_t base = static_cast<std::uint32_t>(mesh_->vertices.size());
  for (int i = 0; i <= major_segments; ++i) {
    const double a = 2 * kPi * i / major_segments;
    const Vec3 radial = std::cos(a) * e1 + std::sin(a) * e2;
    for (int j = 0; j <= minor_segments; ++j) {
      const double b = 2 * kPi * j / minor_segments;
      const Vec3 nn = std::cos(b) * radial + std::sin(b) * n;
      Add(c + major * radial + minor * nn, nn);
    }
  }
  const std::uint32_t row = minor_segments + 1;
  for (int i = 0; i < major_segments; ++i) {
    for (int j = 0; j < minor_segments; ++j) {
      const std::uint32_t a = base + i * row + j, b = a + 1, c2 = a + row, d = c2 + 1;
      Tri(a, c2, b);
      Tri(b, c2, d);
    }
  }
}

void MeshBuilder::Box(const Eigen::Isometry3d& box_frame, const Vec3& half) {
  Blade(box_frame * Eigen::Translation3d(0, 0, -half.z()), 2 * half.z(), 2 * half.x(), 2 * half.y(),
        1.0);
}

void MeshBuilder::Blade(const Eigen::Isometry3d& box_frame, double length, double width,
                        double thickness, double tip_scale) {
  // 8 corners: x = +-w/2, y = +-t/2 at z = 0, scaled by tip_scale at z = length
  Vec3 p[8];
  for (int k = 0; k < 8; ++k) {
    const double sx = (k & 1) ? 0.5 : -0.5, sy = (k & 2) ? 0.5 : -0.5;
    const bool far = (k & 4) != 0;
    const double s = far ? tip_scale : 1.0;
    p[k] = box_frame * Vec3(sx * width * s, sy * thickness * s, far ? length : 0.0);
  }
  // faces as corner quads, counter-clockwise from outside
  static constexpr int kFaces[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                                       {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& f : kFaces) {
    const Vec3 n = (p[f[1]] - p[f[0]]).cross(p[f[2]] - p[f[0]]).normalized();
    std::uint32_t id[4];
    for (int k = 0; k < 4; ++k) id[k] = Add(p[f[k]], n);
    Tri(id[0], id[1], id[2]);
    Tri(id[0], id[2], id[3]);
  }
}

void MeshBuilder::Tube(const std::vector<Vec3>& pts, double r, int sides) {
  const std::size_t n = pts.size();
  if (n < 2) return;
  // tangents by central differences; frame carried along by parallel transport
  std::vector<Vec3> tangent(n);
  for (std::size_t i = 0; i < n; ++i) {
    const Vec3 d = pts[std::min(i + 1, n - 1)] - pts[i > 0 ? i - 1 : 0];
    tangent[i] = d.norm() > 0 ? d.normalized() : (i > 0 ? tangent[i - 1] : Vec3::UnitZ());
  }
  Vec3 normal = AnyOrthogonal(tangent[0]);
  double arc = 0;
  const std::uint32_t base = static_cast<std::uint32_t>(mesh_->vertices.size());
  for (std::size_t i = 0; i < n; ++i) {
    if (i > 0) {
      arc += (pts[i] - pts[i - 1]).norm();
      // remove the component along the new tangent (minimal rotation)
      normal = (normal - normal.dot(tangent[i]) * tangent[i]);
      normal = normal.norm() > 1e-12 ? normal.normalized() : AnyOrthogonal(tangent[i]);
    }
    const Vec3 binormal = tangent[i].cross(normal);
    for (int k = 0; k <= sides; ++k) {
      const double a = 2 * kPi * k / sides;
      const Vec3 radial = std::cos(a) * normal + std::sin(a) * binormal;
      AddWorld(pts[i] + r * radial, radial, static_cast<float>(arc / (2 * r)),
               static_cast<float>(k) / sides);
    }
  }
  const std::uint32_t row = sides + 1;
  for (std::size_t i = 0; i + 1 < n; ++i) {
    for (int k = 0; k < sides; ++k) {
      const std::uint32_t a = base + static_cast<std::uint32_t>(i) * row + k, b = a + 1,
                          c = a + row, d = c + 1;
      Tri(a, b, c);
      Tri(b, d, c);
    }
  }
}

void ComputeVertexNormals(SceneMesh* mesh) {
  std::vector<Vec3> acc(mesh->vertices.size(), Vec3::Zero());
  auto pos = [&](std::uint32_t i) {
    const float* p = mesh->vertices[i].pos;
    return Vec3(p[0], p[1], p[2]);
  };
  for (std::size_t t = 0; t + 2 < mesh->indices.size(); t += 3) {
    const std::uint32_t a = mesh->indices[t], b = mesh->indices[t + 1], c = mesh->indices[t + 2];
    // cross product length = 2 * area: area weighting for free
    const Vec3 n = (pos(b) - pos(a)).cross(pos(c) - pos(a));
    acc[a] += n;
    acc[b] += n;
    acc[c] += n;
  }
  for (std::size_t i = 0; i < acc.size(); ++i) {
    const double len = acc[i].norm();
    const Vec3 n = len > 0 ? Vec3(acc[i] / len) : Vec3::UnitZ();
    for (int k = 0; k < 3; ++k) mesh->vertices[i].normal[k] = static_cast<float>(n[k]);
  }
}

}  // namespace arthrosim::render
