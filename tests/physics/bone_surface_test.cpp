#include "arthrosim/physics/bone_surface.h"

#include <gtest/gtest.h>

#include <cmath>
#include <map>

#include "arthrosim/core/units.h"

namespace arthrosim::physics {
namespace {

// Cube [-h, h]^3 with two outward triangles per face.
mesh::TriMesh Cube(double h) {
  mesh::TriMesh m;
  m.nodes.resize(3, 8);
  for (int i = 0; i < 8; ++i)
    m.nodes.col(i) = Vec3((i & 1) ? h : -h, (i & 2) ? h : -h, (i & 4) ? h : -h);
  const int q[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                       {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& f : q) {
    m.tris.push_back({f[0], f[1], f[2]});
    m.tris.push_back({f[0], f[2], f[3]});
  }
  return m;
}

// Octahedron subdivided `levels` times and projected on a sphere of radius r.
mesh::TriMesh Sphere(double r, int levels) {
  mesh::TriMesh m;
  std::vector<Vec3> p{{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
  std::vector<mesh::Tri> t{{0, 2, 4}, {2, 1, 4}, {1, 3, 4}, {3, 0, 4},
                           {2, 0, 5}, {1, 2, 5}, {3, 1, 5}, {0, 3, 5}};
  for (int l = 0; l < levels; ++l) {
    std::map<std::pair<int, int>, int> mid;
    auto midpoint = [&](int a, int b) {
      const auto key = std::make_pair(std::min(a, b), std::max(a, b));
      auto it = mid.find(key);
      if (it != mid.end()) return it->second;
      p.push_back((p[a] + p[b]).normalized());
      return mid[key] = static_cast<int>(p.size()) - 1;
    };
    std::vector<mesh::Tri> next;
    for (const auto& tr : t) {
      const int ab = midpoint(tr[0], tr[1]), bc = midpoint(tr[1], tr[2]),
                ca = midpoint(tr[2], tr[0]);
      next.push_back({tr[0], ab, ca});
      next.push_back({ab, tr[1], bc});
      next.push_back({ca, bc, tr[2]});
      next.push_back({ab, bc, ca});
    }
    t = next;
  }
  m.nodes.resize(3, static_cast<Eigen::Index>(p.size()));
  for (std::size_t i = 0; i < p.size(); ++i) m.nodes.col(i) = r * p[i].normalized();
  m.tris = t;
  return m;
}

double CapVolume(double r, double h) { return units::kPi * h * h * (3 * r - h) / 3; }

TEST(BoneSurface, VolumeAndWatertightness) {
  const mesh::TriMesh cube = Cube(10);
  EXPECT_TRUE(CheckWatertight(cube).ok());
  EXPECT_NEAR(EnclosedVolume(cube), 8000, 1e-9);
  mesh::TriMesh flipped = cube;
  std::swap(flipped.tris[3][0], flipped.tris[3][1]);
  EXPECT_FALSE(CheckWatertight(flipped).ok());
  mesh::TriMesh open = cube;
  open.tris.pop_back();
  EXPECT_EQ(CheckWatertight(open).boundary_edges, 3);
  mesh::TriMesh degenerate = cube;
  degenerate.tris[0][1] = degenerate.tris[0][0];
  EXPECT_EQ(CheckWatertight(degenerate).degenerate_tris, 1);
  const mesh::TriMesh s = Sphere(5, 4);
  EXPECT_TRUE(CheckWatertight(s).ok());
  EXPECT_NEAR(EnclosedVolume(s), 4.0 / 3 * units::kPi * 125, 0.01 * 4.0 / 3 * units::kPi * 125);
}

TEST(BoneSurface, BurrCapConvergesAndStaysClosed) {
  // Sphere r = 3 centred 1 mm above the cube's top face: removes a cap of height 2.
  const double r = 3, exact = CapVolume(r, 2);
  double prev_err = 1e30;
  for (double h : {1.0, 0.5, 0.25}) {
    BoneState bone;
    bone.surface = Cube(10);
    const double v0 = EnclosedVolume(bone.surface);
    BoneCarveOptions opt;
    opt.max_edge_mm = h;
    opt.rounds = 6;
    const double removed = CarveSphere(&bone, Vec3(0.1, -0.2, 11), r, 100, opt);
    EXPECT_TRUE(CheckWatertight(bone.surface).ok()) << "h = " << h;
    const double v1 = EnclosedVolume(bone.surface);
    EXPECT_NEAR(removed, v0 - v1, 1e-9 * v0);
    EXPECT_NEAR(bone.removed_volume_mm3, v0 - v1, 1e-9 * v0);
    const double err = std::abs(removed - exact) / exact;
    std::printf("burr cap h = %.2f: removed %.5f mm^3, exact %.5f, rel error %.2e, %zu tris\n", h,
                removed, exact, err, bone.surface.tris.size());
    EXPECT_LT(err, 0.6 * prev_err) << "no convergence at h = " << h;
    prev_err = err;
    // Every vertex is outside the burr (up to rounding) or on it.
    for (int i = 0; i < bone.surface.nodes.cols(); ++i)
      EXPECT_GT((bone.surface.nodes.col(i) - Vec3(0.1, -0.2, 11)).norm(), r - 1e-9);
  }
  EXPECT_LT(prev_err, 0.02);
}

TEST(BoneSurface, MaxDepthLimitsAPass) {
  BoneState bone;
  bone.surface = Cube(10);
  BoneCarveOptions opt;
  opt.max_edge_mm = 0.5;
  double total = 0;
  double last = 0;
  for (int pass = 0; pass < 30; ++pass) {
    last = CarveSphere(&bone, Vec3(0, 0, 11), 3, 0.1, opt);
    EXPECT_GE(last, -1e-12);
    total += last;
    if (pass == 0) {
      // One pass moves no top-face point deeper than 0.1 mm below the face.
      for (int i = 0; i < bone.surface.nodes.cols(); ++i) {
        if (bone.surface.nodes(2, i) > 0) {
          EXPECT_GT(bone.surface.nodes(2, i), 10 - 0.1 - 1e-12);
        }
      }
    }
  }
  EXPECT_TRUE(CheckWatertight(bone.surface).ok());
  EXPECT_NEAR(bone.removed_volume_mm3, total, 1e-9 * 8000);
  EXPECT_NEAR(total, CapVolume(3, 2), 0.03 * CapVolume(3, 2));  // 30 x 0.1 > 2 mm cap depth
  EXPECT_LT(last, 1e-6);                                        // converged: nothing left
}

TEST(BoneSurface, AwlParaboloidConverges) {
  const double radius = 2, depth = 3, exact = units::kPi * depth * radius * radius / 2;
  double prev_err = 1e30;
  for (double h : {0.8, 0.4, 0.2}) {
    BoneState bone;
    bone.surface = Cube(10);
    BoneCarveOptions opt;
    opt.max_edge_mm = h;
    opt.rounds = 6;
    const double removed =
        PushAlong(&bone, Vec3(0.05, 0.1, 10), Vec3(0, 0, -1), radius, depth, opt);
    EXPECT_TRUE(CheckWatertight(bone.surface).ok());
    EXPECT_NEAR(bone.removed_volume_mm3, 8000 - EnclosedVolume(bone.surface), 1e-9 * 8000);
    const double err = std::abs(removed - exact) / exact;
    std::printf("awl h = %.2f: removed %.5f mm^3, exact %.5f, rel error %.2e\n", h, removed, exact,
                err);
    EXPECT_LT(err, 0.6 * prev_err);
    prev_err = err;
  }
  EXPECT_LT(prev_err, 0.03);
}

TEST(BoneSurface, CarvingASphereBoneKeepsItClosed) {
  BoneState bone;
  bone.surface = Sphere(10, 4);
  const double v0 = EnclosedVolume(bone.surface);
  double total = 0;
  for (int k = 0; k < 5; ++k) total += CarveSphere(&bone, Vec3(0, 0, 11.5 - 0.5 * k), 2.5, 0.3);
  total += PushAlong(&bone, Vec3(5, 0, std::sqrt(75.0)), Vec3(-0.5, 0, -std::sqrt(0.75)), 1.5, 2);
  EXPECT_TRUE(CheckWatertight(bone.surface).ok());
  EXPECT_GT(total, 1.0);
  EXPECT_NEAR(bone.removed_volume_mm3, v0 - EnclosedVolume(bone.surface), 1e-9 * v0);
  EXPECT_NEAR(total, bone.removed_volume_mm3, 1e-9 * v0);
}

}  // namespace
}  // namespace arthrosim::physics
