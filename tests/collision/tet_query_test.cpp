#include "arthrosim/collision/tet_query.h"

#include <gtest/gtest.h>

#include <random>

#include "clip_reference.h"

namespace arthrosim::collision {
namespace {

using testing::ClipReference;

TEST(TetQuery, TriangleTetTestAgreesWithClippingOnRandomPairs) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  int hits = 0, misses = 0;
  for (int trial = 0; trial < 20000; ++trial) {
    std::array<Vec3, 4> p;
    for (Vec3& q : p) q = Vec3(u(rng), u(rng), u(rng));
    const Vec3 a(u(rng), u(rng), u(rng)), b(u(rng), u(rng), u(rng)), c(u(rng), u(rng), u(rng));
    const bool ref = ClipReference(a, b, c, p);
    ASSERT_EQ(TriangleIntersectsTet(a, b, c, p), ref) << "trial " << trial;
    (ref ? hits : misses) += 1;
  }
  EXPECT_GT(hits, 2000);  // both outcomes well represented
  EXPECT_GT(misses, 2000);
}

TEST(TetQuery, DegenerateTriangleIsASegment) {
  const std::array<Vec3, 4> p{Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0, 0, 1)};
  // A segment through the tet and one beside it.
  EXPECT_TRUE(TriangleIntersectsTet(Vec3(0.1, 0.1, -1), Vec3(0.1, 0.1, 2), Vec3(0.1, 0.1, 2), p));
  EXPECT_FALSE(TriangleIntersectsTet(Vec3(0.9, 0.9, -1), Vec3(0.9, 0.9, 2), Vec3(0.9, 0.9, 2), p));
}

TEST(TetQuery, TreeFindsExactlyTheBruteForceSet) {
  // A 6 x 5 x 4 grid of unit cubes, 6 tets each, with some tets dead.
  Points x(3, 7 * 6 * 5);
  auto id = [](int i, int j, int k) { return i + 7 * (j + 6 * k); };
  for (int k = 0; k < 5; ++k)
    for (int j = 0; j < 6; ++j)
      for (int i = 0; i < 7; ++i) x.col(id(i, j, k)) = Vec3(i, j, k);
  std::vector<mesh::Tet> tets;
  for (int k = 0; k < 4; ++k)
    for (int j = 0; j < 5; ++j)
      for (int i = 0; i < 6; ++i) {
        const int c[8] = {id(i, j, k),         id(i + 1, j, k),        id(i, j + 1, k),
                          id(i + 1, j + 1, k), id(i, j, k + 1),        id(i + 1, j, k + 1),
                          id(i, j + 1, k + 1), id(i + 1, j + 1, k + 1)};
        tets.push_back({c[0], c[1], c[3], c[7]});
        tets.push_back({c[0], c[3], c[2], c[7]});
        tets.push_back({c[0], c[2], c[6], c[7]});
        tets.push_back({c[0], c[6], c[4], c[7]});
        tets.push_back({c[0], c[4], c[5], c[7]});
        tets.push_back({c[0], c[5], c[1], c[7]});
      }
  std::vector<std::uint8_t> alive(tets.size(), 1);
  for (std::size_t t = 0; t < alive.size(); t += 7) alive[t] = 0;
  TetTree tree;
  tree.Build(x, tets);
  // Move the nodes, refit, query.
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(-0.2, 0.2);
  for (int c = 0; c < x.cols(); ++c) x.col(c) += Vec3(u(rng), u(rng), u(rng));
  tree.Refit(x, tets);
  std::uniform_real_distribution<double> w(-1.0, 7.0);
  std::vector<std::int32_t> got;
  for (int q = 0; q < 200; ++q) {
    const Vec3 a(w(rng), w(rng), w(rng)), b(w(rng), w(rng), w(rng)), c(w(rng), w(rng), w(rng));
    tree.QueryTriangle(x, tets, alive, a, b, c, &got);
    std::vector<std::int32_t> want;
    for (std::size_t t = 0; t < tets.size(); ++t) {
      const mesh::Tet& e = tets[t];
      if (alive[t] &&
          TriangleIntersectsTet(a, b, c, {x.col(e[0]), x.col(e[1]), x.col(e[2]), x.col(e[3])})) {
        want.push_back(static_cast<std::int32_t>(t));
      }
    }
    ASSERT_EQ(got, want) << "query " << q;
  }
}

}  // namespace
}  // namespace arthrosim::collision
