#include "arthrosim/physics/corotational_fem.h"

#include <algorithm>
#include <cmath>

#include "arthrosim/core/units.h"

namespace arthrosim::physics {

Lame LameFromMaterial(const Material& material) {
  const double e = material.young_modulus_pa * units::kPascalToInternal;
  const double nu = material.poisson_ratio;
  Lame lame;
  lame.mu = e / (2.0 * (1.0 + nu));
  lame.lambda = e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu));
  return lame;
}

TetRest ComputeTetRest(const Vec3& x0, const Vec3& x1, const Vec3& x2, const Vec3& x3) {
  TetRest rest;
  Mat3 dm;
  dm.col(0) = x1 - x0;
  dm.col(1) = x2 - x0;
  dm.col(2) = x3 - x0;
  const double det = dm.determinant();
  // Degenerate when the volume is tiny against the cube of the longest edge (a sliver that
  // would make Dm^-1 explode), or when the input is not finite.
  double longest = std::max({dm.col(0).norm(), dm.col(1).norm(), dm.col(2).norm(), (x2 - x1).norm(),
                             (x3 - x1).norm(), (x3 - x2).norm()});
  if (!std::isfinite(det) || !std::isfinite(longest) || longest == 0 ||
      std::abs(det) <= 1e-9 * longest * longest * longest) {
    return rest;
  }
  rest.dm_inv = dm.inverse();
  rest.volume = std::abs(det) / 6.0;
  rest.degenerate = false;
  return rest;
}

double ElementEnergy(const TetRest& rest, const Mat3& r, const Mat3& f, const Lame& lame) {
  const Mat3 s = r.transpose() * f;
  Mat3 eps = 0.5 * (s + s.transpose());
  eps.diagonal().array() -= 1.0;
  const double tr = eps.trace();
  return rest.volume * (lame.mu * eps.squaredNorm() + 0.5 * lame.lambda * tr * tr);
}

void ElementStiffnessBlocks(const TetRest& rest, const Mat3& r, const Lame& lame, double scale,
                            std::array<Mat3, 10>* blocks) {
  // Rest-frame shape gradients g_a (rows of Dm^-1, g_0 = -sum) and their rotated images.
  std::array<Vec3, 4> g;
  g[1] = rest.dm_inv.row(0).transpose();
  g[2] = rest.dm_inv.row(1).transpose();
  g[3] = rest.dm_inv.row(2).transpose();
  g[0] = -(g[1] + g[2] + g[3]);
  // Rotated gradients as plain arrays: the 10 blocks below are written out entry by entry
  // (Eigen's outer-product expressions cost several times more on 3x3 blocks).
  double gr[4][3];
  for (int a = 0; a < 4; ++a) {
    const Vec3 v = r * g[a];
    gr[a][0] = v[0];
    gr[a][1] = v[1];
    gr[a][2] = v[2];
  }
  const double v = scale * rest.volume;
  const double vl = v * lame.lambda;
  const double vm = v * lame.mu;
  auto block = [&](int a, int b, Mat3* k) {
    const double* ga = gr[a];
    const double* gb = gr[b];
    for (int j = 0; j < 3; ++j) {
      for (int i = 0; i < 3; ++i) (*k)(i, j) = vl * (ga[i] * gb[j]) + vm * (gb[i] * ga[j]);
    }
    const double d = vm * g[a].dot(g[b]);
    (*k)(0, 0) += d;
    (*k)(1, 1) += d;
    (*k)(2, 2) += d;
  };
  for (int a = 0; a < 4; ++a) block(a, a, &(*blocks)[a]);
  for (int e = 0; e < 6; ++e) block(kTetEdges[e][0], kTetEdges[e][1], &(*blocks)[4 + e]);
}

}  // namespace arthrosim::physics
