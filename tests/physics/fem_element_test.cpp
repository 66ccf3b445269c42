// Element-level checks of the corotational tetrahedron and the polar rotation.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include <Eigen/Dense>
#include <Eigen/Eigenvalues>

#include "arthrosim/core/units.h"
#include "arthrosim/physics/block_ldlt.h"
#include "arthrosim/physics/corotational_fem.h"
#include "arthrosim/physics/polar_decomposition.h"

namespace arthrosim::physics {
namespace {

Mat3 RandomMatrix(std::mt19937_64& rng, double scale) {
  std::uniform_real_distribution<double> u(-scale, scale);
  Mat3 m;
  for (int i = 0; i < 9; ++i) m(i / 3, i % 3) = u(rng);
  return m;
}

Mat3 RandomRotation(std::mt19937_64& rng) {
  std::normal_distribution<double> n(0, 1);
  Quat q(n(rng), n(rng), n(rng), n(rng));
  q.normalize();
  return q.toRotationMatrix();
}

void ExpectRotation(const Mat3& r) {
  EXPECT_NEAR((r.transpose() * r - Mat3::Identity()).norm(), 0, 1e-12);
  EXPECT_NEAR(r.determinant(), 1.0, 1e-12);
}

TEST(PolarRotation, RecoversRotationOfStretch) {
  std::mt19937_64 rng(7);
  for (int k = 0; k < 200; ++k) {
    const Mat3 r = RandomRotation(rng);
    // Symmetric positive definite stretch with eigenvalues in [0.3, 3].
    const Mat3 q = RandomRotation(rng);
    std::uniform_real_distribution<double> u(0.3, 3.0);
    const Mat3 s = q * Eigen::Vector3d(u(rng), u(rng), u(rng)).asDiagonal() * q.transpose();
    const Mat3 got = PolarRotation(r * s);
    ExpectRotation(got);
    EXPECT_NEAR((got - r).norm(), 0, 1e-10) << k;
  }
}

TEST(PolarRotation, FlatAndInvertedElementsGiveProperRotations) {
  std::mt19937_64 rng(11);
  for (int k = 0; k < 200; ++k) {
    Mat3 f = RandomMatrix(rng, 1.0);
    if (k % 3 == 0) f.col(2) = 0.5 * f.col(0) - 0.25 * f.col(1);  // exactly flat
    if (k % 3 == 1 && f.determinant() > 0) f.col(0) = -f.col(0);  // inverted
    const Mat3 r = PolarRotation(f);
    ExpectRotation(r);
    // R^T F must be symmetric: R is the rotation of a (signed) polar decomposition.
    const Mat3 s = r.transpose() * f;
    EXPECT_NEAR((s - s.transpose()).norm(), 0, 1e-10 * f.norm()) << k;
  }
  // A tet squashed through itself: F = diag(1, 1, -0.2) rotates by nothing (reflection pushed
  // onto the smallest singular value).
  ExpectRotation(PolarRotation(Eigen::Vector3d(1, 1, -0.2).asDiagonal()));
  EXPECT_NEAR((PolarRotation(Eigen::Vector3d(1, 1, -0.2).asDiagonal()) - Mat3::Identity()).norm(),
              0, 1e-12);
  ExpectRotation(PolarRotation(Mat3::Zero()));
  ExpectRotation(PolarRotation(Mat3::Constant(std::nan(""))));
}

TEST(PolarRotation, BatchedMatchesSingleAndIgnoresBatching) {
  // Mixed well-conditioned, flat, inverted and non-finite matrices; an odd count leaves a
  // partial batch of lanes.
  std::mt19937_64 rng(13);
  std::vector<Mat3> f;
  for (int k = 0; k < 23; ++k) {
    Mat3 m = k % 2 ? RandomRotation(rng) * (Mat3::Identity() + RandomMatrix(rng, 0.05))
                   : RandomMatrix(rng, 1.0);
    if (k % 7 == 3) m.col(2) = 0.5 * m.col(0) - 0.25 * m.col(1);
    if (k % 7 == 5 && m.determinant() > 0) m.col(0) = -m.col(0);
    if (k == 11) m(1, 2) = std::nan("");
    f.push_back(m);
  }
  std::vector<Mat3> all(f.size()), one(1);
  PolarRotations(f.data(), all.data(), static_cast<int>(f.size()));
  for (std::size_t k = 0; k < f.size(); ++k) {
    ExpectRotation(all[k]);
    EXPECT_NEAR((all[k] - PolarRotation(f[k])).norm(), 0, 1e-14) << k;
    // The same matrix alone in its batch gives the same bits.
    PolarRotations(&f[k], one.data(), 1);
    EXPECT_TRUE((one[0].array() == all[k].array()).all()) << k;
  }
}

TEST(BlockLdlt, SolvesSparseBlockSystemsAndRejectsIndefinite) {
  // A random sparse symmetric positive-definite matrix of 3x3 blocks (a grid of 40 nodes with
  // neighbour and a few long-range pairs: fill and supernodes of several widths), refactored
  // with new values on the same pattern; checked against a dense solve.
  std::mt19937_64 rng(17);
  const std::int32_t n = 40;
  std::vector<std::array<std::int32_t, 2>> pairs;
  for (std::int32_t i = 0; i < n; ++i) {
    if (i % 8 != 7) pairs.push_back({i, i + 1});
    if (i + 8 < n) pairs.push_back({i, i + 8});
    if (i % 5 == 0 && i + 17 < n) pairs.push_back({i, i + 17});
  }
  pairs.push_back({-1, -1});  // ignored entry
  BlockLdlt ldlt;
  ldlt.Analyze(n, pairs);
  for (int round = 0; round < 3; ++round) {
    std::vector<Mat3> diag(static_cast<std::size_t>(n)), blocks(pairs.size(), Mat3::Zero());
    Eigen::MatrixXd dense = Eigen::MatrixXd::Zero(3 * n, 3 * n);
    for (std::size_t e = 0; e + 1 < pairs.size(); ++e) {
      blocks[e] = RandomMatrix(rng, 1.0);
      const auto [i, j] = pairs[e];
      dense.block<3, 3>(3 * i, 3 * j) = blocks[e];
      dense.block<3, 3>(3 * j, 3 * i) = blocks[e].transpose();
    }
    for (std::int32_t i = 0; i < n; ++i) {
      const Mat3 m = RandomMatrix(rng, 1.0);
      diag[static_cast<std::size_t>(i)] = m * m.transpose() + 12.0 * Mat3::Identity();
      dense.block<3, 3>(3 * i, 3 * i) = diag[static_cast<std::size_t>(i)];
    }
    ASSERT_TRUE(ldlt.Factor(diag, blocks)) << round;
    Eigen::VectorXd b(3 * n);
    for (Eigen::Index k = 0; k < b.size(); ++k) b[k] = std::sin(1.0 + k + round);
    Eigen::VectorXd x = b;
    ldlt.Solve(x.data());
    const Eigen::VectorXd ref = dense.ldlt().solve(b);
    EXPECT_LE((x - ref).norm(), 1e-12 * ref.norm()) << round;
    EXPECT_GT(ldlt.factor_nonzeros(), 0);
  }
  // Indefinite: a negative diagonal block.
  std::vector<Mat3> diag(static_cast<std::size_t>(n), Mat3::Identity()),
      blocks(pairs.size(), Mat3::Zero());
  diag[7] = -Mat3::Identity();
  EXPECT_FALSE(ldlt.Factor(diag, blocks));
}

// The factorisation spread over parts (FactorSlice) gives the bits of the whole (Factor), for
// any part count, and refuses parts out of order.
TEST(BlockLdlt, FactorInPartsGivesTheBitsOfTheWhole) {
  std::mt19937_64 rng(5);
  const std::int32_t n = 60;
  std::vector<std::array<std::int32_t, 2>> pairs;
  for (std::int32_t i = 0; i < n; ++i) {
    if (i % 10 != 9) pairs.push_back({i, i + 1});
    if (i + 10 < n) pairs.push_back({i, i + 10});
    if (i % 7 == 0 && i + 23 < n) pairs.push_back({i, i + 23});
  }
  std::vector<Mat3> diag(static_cast<std::size_t>(n)), blocks(pairs.size());
  for (Mat3& b : blocks) b = RandomMatrix(rng, 1.0);
  for (Mat3& d : diag) {
    const Mat3 m = RandomMatrix(rng, 1.0);
    d = m * m.transpose() + 14.0 * Mat3::Identity();
  }
  Eigen::VectorXd b(3 * n);
  for (Eigen::Index k = 0; k < b.size(); ++k) b[k] = std::cos(0.3 * k);
  BlockLdlt whole;
  whole.Analyze(n, pairs);
  ASSERT_TRUE(whole.Factor(diag, blocks));
  Eigen::VectorXd x_whole = b;
  whole.Solve(x_whole.data());
  for (int parts : {1, 2, 3, 6, 1000}) {
    BlockLdlt sliced;
    sliced.Analyze(n, pairs);
    sliced.BeginFactor(diag, blocks);
    EXPECT_FALSE(sliced.ok());
    EXPECT_FALSE(sliced.FactorSlice(1, parts == 1 ? 2 : parts)) << "out of order";
    for (int j = 0; j < parts; ++j) {
      EXPECT_FALSE(sliced.ok()) << parts << " " << j;
      ASSERT_TRUE(sliced.FactorSlice(j, parts)) << parts << " " << j;
    }
    ASSERT_TRUE(sliced.ok()) << parts;
    Eigen::VectorXd x = b;
    sliced.Solve(x.data());
    EXPECT_TRUE((x.array() == x_whole.array()).all()) << parts;
  }
}

struct Tet4 {
  std::array<Vec3, 4> x;
};

Tet4 RestTet() {
  return Tet4{
      {Vec3(0.1, -0.2, 0.3), Vec3(2.1, 0.1, 0.2), Vec3(0.4, 1.9, -0.1), Vec3(0.2, 0.3, 2.4)}};
}

Material Rubber() {
  Material m;
  m.young_modulus_pa = 10e6;
  m.poisson_ratio = 0.3;
  m.density_kg_m3 = 1000;
  return m;
}

TEST(CorotationalTet, RigidRotationsGiveZeroForce) {
  const Tet4 rest = RestTet();
  const TetRest tr = ComputeTetRest(rest.x[0], rest.x[1], rest.x[2], rest.x[3]);
  const Lame lame = LameFromMaterial(Rubber());
  // Reference force scale: the forces of a 1 % stretch.
  std::array<Vec3, 4> f;
  {
    std::array<Vec3, 4> x = rest.x;
    for (Vec3& p : x) p.x() *= 1.01;
    const Mat3 fg = DeformationGradient(tr, x[0], x[1], x[2], x[3]);
    ElementForces(tr, PolarRotation(fg), fg, lame, &f);
  }
  const double scale = f[0].norm() + f[1].norm() + f[2].norm() + f[3].norm();
  std::mt19937_64 rng(3);
  std::vector<Mat3> rotations = {
      Eigen::AngleAxisd(units::kPi / 2, Vec3::UnitZ()).toRotationMatrix(),
      Eigen::AngleAxisd(units::kPi, Vec3::UnitX()).toRotationMatrix(),
      Eigen::AngleAxisd(units::kPi, Vec3(1, 1, 1).normalized()).toRotationMatrix(),
      Eigen::AngleAxisd(-units::kPi / 2, Vec3(0, 1, 1).normalized()).toRotationMatrix()};
  for (int k = 0; k < 20; ++k) rotations.push_back(RandomRotation(rng));
  for (const Mat3& r : rotations) {
    std::array<Vec3, 4> x;
    for (int a = 0; a < 4; ++a) x[a] = r * rest.x[a] + Vec3(50, -20, 7);
    const Mat3 fg = DeformationGradient(tr, x[0], x[1], x[2], x[3]);
    const Mat3 rot = PolarRotation(fg);
    EXPECT_NEAR((rot - r).norm(), 0, 1e-12);
    ElementForces(tr, rot, fg, lame, &f);
    for (int a = 0; a < 4; ++a) EXPECT_LE(f[a].norm(), 1e-12 * scale);
    EXPECT_LE(ElementEnergy(tr, rot, fg, lame), 1e-20 * scale);
  }
}

TEST(CorotationalTet, StiffnessMatchesForceDerivativeAndMatrixFreeProduct) {
  const Tet4 rest = RestTet();
  const TetRest tr = ComputeTetRest(rest.x[0], rest.x[1], rest.x[2], rest.x[3]);
  const Lame lame = LameFromMaterial(Rubber());
  std::mt19937_64 rng(5);
  const Mat3 r = RandomRotation(rng);
  std::array<Mat3, 10> blocks;
  ElementStiffnessBlocks(tr, r, lame, 2.5, &blocks);
  // Full 12x12 from blocks.
  Eigen::Matrix<double, 12, 12> k;
  for (int a = 0; a < 4; ++a) k.block<3, 3>(3 * a, 3 * a) = blocks[a];
  for (int e = 0; e < 6; ++e) {
    const int a = kTetEdges[e][0], b = kTetEdges[e][1];
    k.block<3, 3>(3 * a, 3 * b) = blocks[4 + e];
    k.block<3, 3>(3 * b, 3 * a) = blocks[4 + e].transpose();
  }
  EXPECT_NEAR((k - k.transpose()).norm(), 0, 1e-9 * k.norm());
  // Symmetric positive semi-definite with exactly 6 zero modes (rigid motions).
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 12, 12>> eig(k);
  for (int i = 0; i < 6; ++i) EXPECT_NEAR(eig.eigenvalues()(i), 0, 1e-9 * k.norm());
  EXPECT_GT(eig.eigenvalues()(6), 1e-3 * k.norm());
  // Matrix-free product equals the block product.
  for (int trial = 0; trial < 5; ++trial) {
    std::array<Vec3, 4> dx, y{Vec3::Zero(), Vec3::Zero(), Vec3::Zero(), Vec3::Zero()};
    Eigen::Matrix<double, 12, 1> d;
    for (int a = 0; a < 4; ++a) {
      dx[a] = Vec3::Random();
      d.segment<3>(3 * a) = dx[a];
    }
    ElementStiffnessProduct(tr, r, lame, 2.5, dx, &y);
    const Eigen::Matrix<double, 12, 1> kd = k * d;
    for (int a = 0; a < 4; ++a)
      EXPECT_NEAR((y[a] - kd.segment<3>(3 * a)).norm(), 0, 1e-10 * kd.norm());
  }
  // With the rotation frozen, K = -df/dx (central differences of the forces).
  std::array<Vec3, 4> x;
  for (int a = 0; a < 4; ++a) x[a] = r * rest.x[a] + Vec3(0.01 * a, -0.02, 0.015 * a * a);
  const Mat3 fg0 = DeformationGradient(tr, x[0], x[1], x[2], x[3]);
  const Mat3 rot = PolarRotation(fg0);
  ElementStiffnessBlocks(tr, rot, lame, 1.0, &blocks);
  for (int a = 0; a < 4; ++a) k.block<3, 3>(3 * a, 3 * a) = blocks[a];
  for (int e = 0; e < 6; ++e) {
    const int a = kTetEdges[e][0], b = kTetEdges[e][1];
    k.block<3, 3>(3 * a, 3 * b) = blocks[4 + e];
    k.block<3, 3>(3 * b, 3 * a) = blocks[4 + e].transpose();
  }
  const double eps = 1e-6;
  for (int col = 0; col < 12; ++col) {
    std::array<Vec3, 4> xp = x, xm = x, fp, fm;
    xp[col / 3](col % 3) += eps;
    xm[col / 3](col % 3) -= eps;
    const Mat3 fgp = DeformationGradient(tr, xp[0], xp[1], xp[2], xp[3]);
    const Mat3 fgm = DeformationGradient(tr, xm[0], xm[1], xm[2], xm[3]);
    ElementForces(tr, rot, fgp, lame, &fp);
    ElementForces(tr, rot, fgm, lame, &fm);
    for (int a = 0; a < 4; ++a) {
      const Vec3 dfd = -(fp[a] - fm[a]) / (2 * eps);
      EXPECT_NEAR((dfd - k.block<3, 1>(3 * a, col)).norm(), 0, 1e-6 * k.norm());
    }
  }
}

TEST(CorotationalTet, DegenerateRestIsFlagged) {
  EXPECT_TRUE(
      ComputeTetRest(Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(1, 1, 0)).degenerate);
  const TetRest inv = ComputeTetRest(Vec3(0, 0, 0), Vec3(0, 1, 0), Vec3(1, 0, 0), Vec3(0, 0, 1));
  EXPECT_FALSE(inv.degenerate);
  EXPECT_NEAR(inv.volume, 1.0 / 6.0, 1e-15);
}

}  // namespace
}  // namespace arthrosim::physics
