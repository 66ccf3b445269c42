#pragma once
// Tool against rigid bone as a geometric query (no forces): how far an instrument's collision
// primitives are from the current bone surfaces, signed (bone surfaces are closed, so inside is
// negative), with the nearest bone point and the direction that leads out. The tool proxy (sim)
// uses it to keep instruments outside bone; the bone operations use the contact it reports.
#include <cstdint>
#include <utility>
#include <vector>

#include "arthrosim/collision/collision_mesh.h"
#include "arthrosim/collision/instrument_shape.h"
#include "arthrosim/collision/proximity.h"
#include "arthrosim/core/state.h"

namespace arthrosim::collision {

/// Search trees over the current bone surfaces (derived data: rebuilt from State at will).
struct BoneQueryWorld {
  struct Entry {
    bool built = false;
    std::uint64_t revision = 0;  ///< BoneState::revision the tree was built from
    std::vector<Vec3> positions;
    std::vector<mesh::Tri> tris;
    TriangleBvh bvh;
  };
  std::vector<Entry> bones;
  /// Incremented whenever SyncBoneQuery rebuilds a tree: equal generations, the same surfaces.
  std::uint64_t generation = 0;
  /// A candidate triangle and its exact closest pair to the query's core.
  struct Tested {
    std::int32_t tri = -1;
    ClosestPair pair;
  };
  std::vector<std::int32_t> candidates;  ///< scratch of the queries
  std::vector<double> lower_bounds;      ///< scratch: per candidate a lower bound of its distance
  std::vector<Tested> tested;            ///< scratch: the candidates tested exactly
  std::vector<std::pair<double, std::int32_t>> heap;  ///< scratch of the best-first search
  /// Exact core-triangle distance tests the queries did (a work counter for tests and benches).
  std::int64_t exact_tests = 0;
  /// Candidate triangles ToolBoneClearance reached (their box lower bound within the search's
  /// cutoff; a work counter).
  std::int64_t gathered = 0;
};

/// Rebuilds the trees of bones whose surface changed (revision or size) since the last call.
void SyncBoneQuery(const State& state, BoneQueryWorld* world);

/// The nearest approach of a set of rounded primitives to bone.
struct ToolBoneHit {
  /// Smallest (signed core distance - radius) over the contacting primitives, mm: > 0 clear,
  /// < 0 overlapping bone. Capped at the query reach when no bone is that near.
  double clearance_mm = 0;
  std::int32_t bone = -1;        ///< bone index of the nearest approach, -1 if none in reach
  std::int32_t primitive = -1;   ///< index into the primitives given
  Vec3 point_mm = Vec3::Zero();  ///< nearest bone surface point, mm
  Vec3 normal = Vec3::UnitZ();   ///< unit direction out of the bone at that point
};

/// Clearance of world-frame primitives (those with contacts = true) from every bone, searching
/// within reach_mm (> 0) of each primitive's surface. Exact for overlaps shallower than the
/// primitive radius plus reach_mm; a core entirely deeper inside than reach_mm is not seen.
ToolBoneHit ToolBoneClearance(const std::vector<ToolPrimitive>& primitives, double reach_mm,
                              BoneQueryWorld* world);

/// Signed distance of a point from the bones, mm: the smallest over bones (> 0 outside all,
/// < 0 inside one; +infinity without bones). Exact at any depth (searches until the nearest
/// triangle is found).
double PointBoneSignedDistance(const Vec3& p, BoneQueryWorld* world);

}  // namespace arthrosim::collision
