#pragma once
// Linear corotational tetrahedron (Mueller & Gross 2004 style): the element rotation R is the
// polar rotation of F = Ds Dm^-1, the strain is eps = sym(R^T F) - I, the stress Hooke's law.
// The rotation is frozen in the stiffness (no geometric term), as in SOFA's corotational FEM.
// Internal units: mm, kg, s; stress and Lame parameters in mN/mm^2 (kPa); force in mN.
#include <array>

#include "arthrosim/core/model.h"
#include "arthrosim/core/types.h"

namespace arthrosim::physics {

/// Lame parameters in internal units (mN/mm^2).
struct Lame {
  double lambda = 0;
  double mu = 0;
};

/// Lame parameters of a material (E in Pa, nu) converted to mN/mm^2.
Lame LameFromMaterial(const Material& material);

/// Rest data of one tet: inverse rest edge matrix and rest volume.
struct TetRest {
  Mat3 dm_inv = Mat3::Identity();  ///< inverse of [X1-X0, X2-X0, X3-X0], 1/mm
  double volume = 0;               ///< |det| / 6, mm^3 (an inverted rest tet counts positive)
  bool degenerate = true;  ///< volume too small relative to its edges: no stiffness, no mass
};

/// Rest data from the four rest positions (mm).
TetRest ComputeTetRest(const Vec3& x0, const Vec3& x1, const Vec3& x2, const Vec3& x3);

/// Deformation gradient F = Ds Dm^-1 of current positions (dimensionless).
inline Mat3 DeformationGradient(const TetRest& rest, const Vec3& x0, const Vec3& x1, const Vec3& x2,
                                const Vec3& x3) {
  Mat3 ds;
  ds.col(0) = x1 - x0;
  ds.col(1) = x2 - x0;
  ds.col(2) = x3 - x0;
  return ds * rest.dm_inv;
}

/// Corotational stress (mN/mm^2) in the rotated frame, for eps = sym(R^T F) - I.
inline Mat3 CorotationalStress(const Mat3& r, const Mat3& f, const Lame& lame) {
  const Mat3 s = r.transpose() * f;
  Mat3 eps = 0.5 * (s + s.transpose());
  eps.diagonal().array() -= 1.0;
  Mat3 sigma = (2.0 * lame.mu) * eps;
  sigma.diagonal().array() += lame.lambda * eps.trace();
  return sigma;
}

/// Elastic forces (mN) on the 4 nodes: f_a = -V R sigma g_a, with g_a the shape gradients.
inline void ElementForces(const TetRest& rest, const Mat3& r, const Mat3& f, const Lame& lame,
                          std::array<Vec3, 4>* out) {
  const Mat3 h = (-rest.volume) * (r * CorotationalStress(r, f, lame)) * rest.dm_inv.transpose();
  (*out)[1] = h.col(0);
  (*out)[2] = h.col(1);
  (*out)[3] = h.col(2);
  (*out)[0] = -(h.col(0) + h.col(1) + h.col(2));
}

/// Elastic energy (mN mm) V (mu eps:eps + lambda/2 tr(eps)^2).
double ElementEnergy(const TetRest& rest, const Mat3& r, const Mat3& f, const Lame& lame);

/// Adds scale * K_e dx to y for one element (K_e = R K_local R^T, positive semi-definite):
/// the matrix-free product. dx and y hold the 4 node vectors.
inline void ElementStiffnessProduct(const TetRest& rest, const Mat3& r, const Lame& lame,
                                    double scale, const std::array<Vec3, 4>& dx,
                                    std::array<Vec3, 4>* y) {
  Mat3 dds;
  dds.col(0) = dx[1] - dx[0];
  dds.col(1) = dx[2] - dx[0];
  dds.col(2) = dx[3] - dx[0];
  const Mat3 l = r.transpose() * dds * rest.dm_inv;
  Mat3 sigma = lame.mu * (l + l.transpose());
  sigma.diagonal().array() += lame.lambda * l.trace();
  const Mat3 h = (scale * rest.volume) * (r * sigma) * rest.dm_inv.transpose();
  (*y)[1] += h.col(0);
  (*y)[2] += h.col(1);
  (*y)[3] += h.col(2);
  (*y)[0] -= h.col(0) + h.col(1) + h.col(2);
}

/// The 10 distinct 3x3 blocks K_ab (a <= b) of scale * R K_local R^T, in the order
/// (0,0),(1,1),(2,2),(3,3),(0,1),(0,2),(0,3),(1,2),(1,3),(2,3). K_ba = K_ab^T.
void ElementStiffnessBlocks(const TetRest& rest, const Mat3& r, const Lame& lame, double scale,
                            std::array<Mat3, 10>* blocks);

/// Node pairs (a, b) of the off-diagonal blocks, in the order used above (entries 4..9).
inline constexpr std::array<std::array<int, 2>, 6> kTetEdges{
    {{0, 1}, {0, 2}, {0, 3}, {1, 2}, {1, 3}, {2, 3}}};

}  // namespace arthrosim::physics
