#pragma once
// Rotation part of a 3x3 deformation gradient, robust to flat and inverted elements.
#include "arthrosim/core/types.h"

namespace arthrosim::physics {

/// Proper rotation R (det +1) closest to F. Well-conditioned F (det clearly > 0) uses a scaled
/// Newton polar iteration; flat, inverted or non-finite F falls back to an SVD whose smallest
/// singular direction is flipped so that R stays a rotation. A pure function of F.
Mat3 PolarRotation(const Mat3& f);

/// r[i] = the rotation of f[i] for i < count, by PolarRotation's method with the Newton steps of
/// four matrices interleaved (vectorised); each r[i] depends on f[i] only (not on the batching).
void PolarRotations(const Mat3* f, Mat3* r, int count);

}  // namespace arthrosim::physics
