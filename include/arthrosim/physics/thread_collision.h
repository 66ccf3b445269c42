#pragma once
// Deterministic broad phase for thread segments: sweep-and-prune along x over axis-aligned boxes.
#include <array>
#include <vector>

#include "arthrosim/core/types.h"

namespace arthrosim::physics {

/// Axis-aligned box, mm.
struct Box3 {
  Vec3 min = Vec3::Zero();
  Vec3 max = Vec3::Zero();
};

/// Box around the segment at start and end of a step (a0, a1 -> b0, b1), grown by `pad` mm.
Box3 SweptSegmentBox(const Vec3& a0, const Vec3& a1, const Vec3& b0, const Vec3& b1, double pad);

/// All pairs (i < j) of overlapping boxes, sorted lexicographically. Sorting by (min.x, index)
/// makes the result independent of input order ties and of the platform's sort.
std::vector<std::array<int, 2>> OverlappingPairs(const std::vector<Box3>& boxes);

/// Same pairs written into *pairs, with *order as sort scratch (no allocation once both have
/// grown to the sizes needed).
void OverlappingPairs(const std::vector<Box3>& boxes, std::vector<int>* order,
                      std::vector<std::array<int, 2>>* pairs);

}  // namespace arthrosim::physics
