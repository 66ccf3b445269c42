// Boundary extraction: closed, outward, same node indices, deterministic order; the incremental
// tracker always equals a from-scratch extraction.
#include "arthrosim/mesh/surface.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>

#include "arthrosim/mesh/mesh_summary.h"
#include "arthrosim/mesh/mesh_validate.h"
#include "mesh_test_util.h"

namespace arthrosim::mesh {
namespace {

struct Lcg {
  std::uint64_t s;
  std::uint32_t Next() {
    s = s * 6364136223846793005ull + 1442695040888963407ull;
    return static_cast<std::uint32_t>(s >> 33);
  }
};

/// Every undirected edge of the faces used exactly twice, once in each direction.
void ExpectClosedAndConsistent(const std::vector<BoundaryFace>& faces) {
  std::map<std::pair<std::int32_t, std::int32_t>, int> directed;
  for (const BoundaryFace& f : faces) {
    for (int k = 0; k < 3; ++k) ++directed[{f.nodes[k], f.nodes[(k + 1) % 3]}];
  }
  for (const auto& [e, count] : directed) {
    ASSERT_EQ(count, 1) << "edge " << e.first << "-" << e.second << " used twice the same way";
    ASSERT_EQ(directed.count({e.second, e.first}), 1u)
        << "edge " << e.first << "-" << e.second << " has no opposite: surface not closed";
  }
}

/// Each directed edge used as often as its reverse: a closed oriented surface that may touch
/// itself along edges or at vertices (random removals leave tets joined only by an edge).
void ExpectBalanced(const std::vector<BoundaryFace>& faces) {
  std::map<std::pair<std::int32_t, std::int32_t>, int> directed;
  for (const BoundaryFace& f : faces) {
    for (int k = 0; k < 3; ++k) ++directed[{f.nodes[k], f.nodes[(k + 1) % 3]}];
  }
  for (const auto& [e, count] : directed) {
    const auto it = directed.find({e.second, e.first});
    ASSERT_TRUE(it != directed.end() && it->second == count)
        << "edge " << e.first << "-" << e.second << " is not balanced";
  }
}

TriMesh AsTriMesh(const Points& nodes, const std::vector<BoundaryFace>& faces) {
  TriMesh s;
  s.nodes = nodes;
  for (const BoundaryFace& f : faces) s.tris.push_back(f.nodes);
  return s;
}

double AliveVolume(const TetMesh& m, const std::vector<std::uint8_t>& alive) {
  double v = 0;
  for (std::size_t t = 0; t < m.tets.size(); ++t) {
    if (alive[t]) v += TetSignedVolume(m.nodes, m.tets[t]);
  }
  return v;
}

TEST(BoundaryTest, KuhnCubeBoundaryIsClosedOutwardAndIndexedLikeTheTets) {
  const int n = 4;
  TetMesh m = testing::KuhnCube(n, 0.5);
  // Vary each tet's node order by even permutations (orientation kept) so that every local
  // face number occurs on the boundary.
  const int even[5][4] = {{0, 1, 2, 3}, {1, 2, 0, 3}, {2, 0, 1, 3}, {0, 2, 3, 1}, {1, 0, 3, 2}};
  for (std::size_t i = 0; i < m.tets.size(); ++i) {
    const Tet t = m.tets[i];
    for (int k = 0; k < 4; ++k) m.tets[i][k] = t[even[i % 5][k]];
  }
  int per_face[4] = {0, 0, 0, 0};
  const std::vector<BoundaryFace> faces = ExtractBoundary(m.tets);
  EXPECT_EQ(faces.size(), static_cast<std::size_t>(6 * n * n * 2));
  ExpectClosedAndConsistent(faces);
  const double v = TotalVolume(m);
  EXPECT_NEAR(v, 8.0, 1e-12);
  EXPECT_NEAR(EnclosedVolume(AsTriMesh(m.nodes, faces)), v, 1e-9 * v);
  for (std::size_t i = 0; i < faces.size(); ++i) {
    const BoundaryFace& f = faces[i];
    const Tet& t = m.tets[static_cast<std::size_t>(f.tet)];
    EXPECT_EQ(f.nodes, TetFace(t, f.face));
    ++per_face[f.face];
    EXPECT_EQ(std::count(f.nodes.begin(), f.nodes.end(), t[f.face]), 0);  // opposite node
    // Outward: the normal points away from the owning tet's centroid.
    const Vec3 a = m.nodes.col(f.nodes[0]), b = m.nodes.col(f.nodes[1]),
               c = m.nodes.col(f.nodes[2]);
    const Vec3 centroid =
        0.25 * (m.nodes.col(t[0]) + m.nodes.col(t[1]) + m.nodes.col(t[2]) + m.nodes.col(t[3]));
    EXPECT_GT((b - a).cross(c - a).dot((a + b + c) / 3.0 - centroid), 0.0);
    if (i > 0) {
      const BoundaryFace& p = faces[i - 1];
      EXPECT_TRUE(p.tet < f.tet || (p.tet == f.tet && p.face < f.face)) << "not sorted at " << i;
    }
  }
  for (int f = 0; f < 4; ++f) EXPECT_GT(per_face[f], 0) << "local face " << f;
}

TEST(BoundaryTest, GmshBoxBoundaryIsTheSkinGroup) {
  const MeshData d = ReadMesh(testing::DataPath("box_msh41.msh"));
  const std::vector<BoundaryFace> faces = ExtractBoundary(d.volume.tets);
  ExpectClosedAndConsistent(faces);
  auto key = [](Tri t) {
    std::sort(t.begin(), t.end());
    return t;
  };
  std::vector<Tri> a, b;
  for (const BoundaryFace& f : faces) a.push_back(key(f.nodes));
  for (const Tri& t : d.surface.tris) b.push_back(key(t));
  std::sort(a.begin(), a.end());
  std::sort(b.begin(), b.end());
  EXPECT_EQ(a, b);
  EXPECT_NEAR(EnclosedVolume(AsTriMesh(d.volume.nodes, faces)), 8.0, 1e-9 * 8.0);
}

TEST(BoundaryTest, AliveMaskMatchesExtractingTheSubset) {
  const TetMesh m = testing::KuhnCube(3, 1.0);
  std::vector<std::uint8_t> alive(m.tets.size(), 1);
  Lcg rng{5};
  for (int k = 0; k < 40; ++k) alive[rng.Next() % alive.size()] = 0;
  const std::vector<BoundaryFace> masked = ExtractBoundary(m.tets, alive);
  // Same faces from the compacted subset, with tet indices mapped back.
  std::vector<Tet> subset;
  std::vector<std::int32_t> back;
  for (std::size_t t = 0; t < m.tets.size(); ++t) {
    if (alive[t]) {
      subset.push_back(m.tets[t]);
      back.push_back(static_cast<std::int32_t>(t));
    }
  }
  std::vector<BoundaryFace> sub = ExtractBoundary(subset);
  for (BoundaryFace& f : sub) f.tet = back[static_cast<std::size_t>(f.tet)];
  EXPECT_EQ(masked, sub);
  ExpectBalanced(masked);
  const double v = AliveVolume(m, alive);
  EXPECT_NEAR(EnclosedVolume(AsTriMesh(m.nodes, masked)), v, 1e-9 * v);
}

TEST(BoundaryTrackerTest, RandomRemovalsMatchFromScratchExtraction) {
  const TetMesh m = testing::KuhnCube(4, 0.25);
  BoundaryTracker tracker(m.tets);
  EXPECT_EQ(tracker.Faces(), ExtractBoundary(m.tets));
  std::vector<std::uint8_t> alive(m.tets.size(), 1);
  Lcg rng{99};
  for (int step = 0; step < 250; ++step) {
    const auto t = static_cast<std::int32_t>(rng.Next() % m.tets.size());
    tracker.RemoveTet(t);
    alive[static_cast<std::size_t>(t)] = 0;
    if (step % 10 == 0 || step > 240) {
      const std::vector<BoundaryFace> expect = ExtractBoundary(m.tets, alive);
      ASSERT_EQ(tracker.Faces(), expect) << "after step " << step;
      ASSERT_EQ(tracker.num_faces(), expect.size());
      ExpectBalanced(expect);
      const double v = AliveVolume(m, alive);
      ASSERT_NEAR(EnclosedVolume(AsTriMesh(m.nodes, expect)), v, 1e-9 * std::max(v, 1e-3));
    }
  }
  EXPECT_EQ(tracker.alive(), alive);
  // Revive some: still equal.
  for (std::int32_t t = 0; t < 50; ++t) {
    tracker.ReviveTet(t);
    alive[static_cast<std::size_t>(t)] = 1;
  }
  EXPECT_EQ(tracker.Faces(), ExtractBoundary(m.tets, alive));
  EXPECT_THROW(tracker.RemoveTet(-1), std::out_of_range);
  EXPECT_THROW(tracker.RemoveTet(static_cast<std::int32_t>(m.tets.size())), std::out_of_range);
}

TEST(BoundaryTrackerTest, SplittingTetsByAddingKeepsTheSurfaceClosedAndTheVolume) {
  TetMesh m = testing::KuhnCube(2, 1.0);
  BoundaryTracker tracker(m.tets);
  std::vector<std::uint8_t> alive(m.tets.size(), 1);
  // Split every third tet at its centroid into 4 tets (new node), as a cutter would.
  const std::size_t original = m.tets.size();
  for (std::size_t t = 0; t < original; t += 3) {
    const Tet old = m.tets[t];
    const Vec3 c = 0.25 * (m.nodes.col(old[0]) + m.nodes.col(old[1]) + m.nodes.col(old[2]) +
                           m.nodes.col(old[3]));
    const auto nc = static_cast<std::int32_t>(m.nodes.cols());
    m.nodes.conservativeResize(3, nc + 1);
    m.nodes.col(nc) = c;
    tracker.RemoveTet(static_cast<std::int32_t>(t));
    alive[t] = 0;
    for (int f = 0; f < 4; ++f) {
      const Tri face = TetFace(old, f);
      // Face f is outward for the old tet, so (face reversed, centroid) is positive.
      const Tet child{face[0], face[2], face[1], nc};
      EXPECT_GT(TetSignedVolume(m.nodes, child), 0);
      m.tets.push_back(child);
      alive.push_back(1);
      EXPECT_EQ(tracker.AddTet(child), static_cast<std::int32_t>(m.tets.size() - 1));
    }
  }
  const std::vector<BoundaryFace> expect = ExtractBoundary(m.tets, alive);
  EXPECT_EQ(tracker.Faces(), expect);
  EXPECT_EQ(expect.size(), static_cast<std::size_t>(6 * 2 * 2 * 2));
  ExpectClosedAndConsistent(expect);
  EXPECT_NEAR(EnclosedVolume(AsTriMesh(m.nodes, expect)), 8.0, 1e-9 * 8.0);
  EXPECT_NEAR(AliveVolume(m, alive), 8.0, 1e-12);
}

TEST(SummaryTest, CountsBoundingBoxAndGroups) {
  const MeshData d = ReadMesh(testing::DataPath("box_msh22.msh"));
  const MeshSummary s = Summarize(d);
  EXPECT_EQ(s.format, "msh2.2");
  EXPECT_EQ(s.num_nodes, d.num_nodes());
  EXPECT_EQ(s.num_tets, static_cast<std::int64_t>(d.volume.tets.size()));
  EXPECT_EQ(s.num_tris, static_cast<std::int64_t>(d.surface.tris.size()));
  EXPECT_EQ(s.num_lines, 2);
  EXPECT_EQ(s.bbox_min_mm, Vec3(0, 0, 0));
  EXPECT_EQ(s.bbox_max_mm, Vec3(4, 2, 1));
  EXPECT_NEAR(s.tet_volume_mm3, 8.0, 1e-12);
  EXPECT_EQ(s.num_boundary_faces, s.num_tris);
  ASSERT_EQ(s.groups.size(), 4u);
  const std::string text = FormatSummary(s);
  EXPECT_NE(text.find("group: dim 3 tag 7 \"tendon\""), std::string::npos) << text;
  EXPECT_NE(text.find("bbox_mm: [0, 0, 0] .. [4, 2, 1]"), std::string::npos) << text;
}

}  // namespace
}  // namespace arthrosim::mesh
