// Boundary extraction and FCL AABB trees: refit-tree candidates equal brute force.
#include "arthrosim/collision/collision_mesh.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "arthrosim/collision/bench_scene.h"
#include "arthrosim/core/rng.h"

namespace arthrosim::collision {
namespace {

std::vector<Vec3> Cols(const Points& p) {
  std::vector<Vec3> v;
  for (Eigen::Index i = 0; i < p.cols(); ++i) v.push_back(p.col(i));
  return v;
}

double EnclosedVolume(const std::vector<Vec3>& p, const std::vector<mesh::Tri>& tris) {
  double v = 0;
  for (const mesh::Tri& t : tris) v += p[t[0]].dot(p[t[1]].cross(p[t[2]])) / 6.0;
  return v;
}

TEST(CollisionMesh, BoundaryOfABoxIsClosedOutwardAndOrderFree) {
  const mesh::TetMesh m = BoxTets(Vec3(0, 0, 0), Vec3(4, 3, 2), 4, 3, 2);
  const std::vector<mesh::Tri> tris = BoundaryTriangles(m.tets, {});
  EXPECT_EQ(tris.size(), 2u * 2u * (4 * 3 + 3 * 2 + 4 * 2));
  EXPECT_NEAR(EnclosedVolume(Cols(m.nodes), tris), 24.0, 1e-12);  // outward: +volume
  // Removing a corner tet exposes its faces; the enclosed volume drops by its volume.
  std::vector<std::uint8_t> alive(m.tets.size(), 1);
  alive[0] = 0;
  const auto cut = BoundaryTriangles(m.tets, alive);
  EXPECT_NEAR(EnclosedVolume(Cols(m.nodes), cut), 24.0 - 1.0 / 6.0, 1e-12);
  // Reversed tet order and rotated (even permutation) tet nodes give the same list.
  std::vector<mesh::Tet> shuffled(m.tets.rbegin(), m.tets.rend());
  for (mesh::Tet& t : shuffled) {
    const mesh::Tet o = t;
    t = {o[1], o[2], o[0], o[3]};
  }
  EXPECT_EQ(BoundaryTriangles(shuffled, {}), tris);
  const Surface s = MakeSurface(tris);
  for (std::size_t t = 0; t < tris.size(); ++t) {
    for (int k = 0; k < 3; ++k) EXPECT_EQ(s.vertices[s.local_tris[t][k]], tris[t][k]);
  }
}

Box TriBox(const std::vector<Vec3>& p, const mesh::Tri& t) {
  Box b;
  for (int k = 0; k < 3; ++k) b.Add(p[t[k]]);
  return b;
}

TEST(CollisionMesh, RefitTreeCandidatesEqualBruteForceOn1000Deformations) {
  const mesh::TetMesh block = BoxTets(Vec3(-6, -6, 0), Vec3(6, 6, 4), 6, 6, 2);
  const Surface surf = MakeSurface(BoundaryTriangles(block.tets, {}));
  std::vector<Vec3> rest;
  for (std::int32_t v : surf.vertices) rest.push_back(block.nodes.col(v));
  const mesh::TriMesh bone = Ellipsoid(Vec3(0, 0, -6), Vec3(9, 9, 6), 16, 10);
  const Surface bsurf = MakeSurface(CanonicalTriangles(bone.tris));
  std::vector<Vec3> bpos;
  for (std::int32_t v : bsurf.vertices) bpos.push_back(bone.nodes.col(v));
  TriangleBvh tree, btree;
  tree.Build(rest, surf.local_tris);  // built once on the rest shape, then only refit
  btree.Build(bpos, bsurf.local_tris);
  std::uint64_t rng = 99;
  std::vector<Vec3> pos(rest.size());
  std::int64_t total_hits = 0, total_pairs = 0;
  for (int config = 0; config < 1000; ++config) {
    // Large smooth deformation plus per-vertex noise: the refit tree's topology is now poor,
    // but it must stay conservative and exact at the leaves.
    const double a = 3 * NextUniform(&rng), w = 0.5 * NextUniform(&rng), ph = 6 * NextUniform(&rng);
    for (std::size_t i = 0; i < rest.size(); ++i) {
      const Vec3& r = rest[i];
      pos[i] =
          r +
          Vec3(a * std::sin(w * r.y() + ph), 0.5 * a * std::cos(w * r.x()),
               a * std::sin(w * (r.x() + r.y()) + ph)) +
          0.5 * Vec3(NextUniform(&rng) - 0.5, NextUniform(&rng) - 0.5, NextUniform(&rng) - 0.5);
    }
    tree.Refit(pos);
    Box query;
    query.Add(
        Vec3(12 * NextUniform(&rng) - 6, 12 * NextUniform(&rng) - 6, 6 * NextUniform(&rng) - 1));
    query = query.Inflated(0.5 + 3 * NextUniform(&rng));
    std::vector<std::int32_t> got, want;
    tree.Query(query, &got);
    for (std::size_t t = 0; t < surf.local_tris.size(); ++t) {
      if (TriBox(pos, surf.local_tris[t]).Overlaps(query)) want.push_back(static_cast<int>(t));
    }
    ASSERT_EQ(got, want) << "config " << config;
    total_hits += static_cast<std::int64_t>(want.size());
    const double margin = 1.0;
    std::vector<std::pair<std::int32_t, std::int32_t>> pairs, brute;
    tree.QueryPairs(btree, margin, &pairs);
    for (std::size_t t = 0; t < surf.local_tris.size(); ++t) {
      const Box bt = TriBox(pos, surf.local_tris[t]).Inflated(margin);
      for (std::size_t u = 0; u < bsurf.local_tris.size(); ++u) {
        if (bt.Overlaps(TriBox(bpos, bsurf.local_tris[u]))) {
          brute.emplace_back(static_cast<int>(t), static_cast<int>(u));
        }
      }
    }
    ASSERT_EQ(pairs, brute) << "config " << config;
    total_pairs += static_cast<std::int64_t>(brute.size());
  }
  // The test exercised non-trivial results.
  EXPECT_GT(total_hits, 10000);
  EXPECT_GT(total_pairs, 10000);
}

}  // namespace
}  // namespace arthrosim::collision
