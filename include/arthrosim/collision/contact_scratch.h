#pragma once
// Work lists of the collision stage (Detect), kept in the Workspace (CollisionWorld::scratch) so
// that a step after the first allocates nothing and the whole state of the stage is visible.
// Nothing here carries information from one step to the next: every list is cleared or
// overwritten before it is read, so a fresh (empty) scratch gives the same contacts bit for bit.
#include <array>
#include <cstdint>
#include <utility>
#include <vector>

#include "arthrosim/collision/collision_mesh.h"
#include "arthrosim/collision/instrument_shape.h"
#include "arthrosim/collision/proximity.h"
#include "arthrosim/core/state.h"
#include "arthrosim/physics/contact.h"

namespace arthrosim::collision {

/// Nearest surface feature to a query simplex among candidate triangles, with the pseudo-normal
/// of all equally near triangles (sum of their face normals) to tell inside from outside at
/// edges and vertices.
struct Nearest {
  bool found = false;
  std::int32_t tri = -1;
  ClosestPair pair;  ///< a = query, b = triangle
  double dist = 0;   ///< mm
  Vec3 pseudo = Vec3::UnitZ();
  /// Signed distance of the query point from the surface (> 0 outside), mm.
  double Signed() const { return (pair.pa - pair.pb).dot(pseudo) >= 0 ? dist : -dist; }
};

/// A tool primitive swept from last step's pose (sub[0]) to this step's (sub.back()).
struct Sweep {
  const ToolPrimitive* prim = nullptr;
  std::vector<Simplex> sub;
  std::vector<Box> sub_box;  ///< box of each substep core, mm
  Box box;                   ///< of all substeps, not inflated, mm
};

/// Segment boxes of one thread (empty boxes for dead segments) and boxes of runs of
/// consecutive segments (to skip a far thread fast), mm.
struct ThreadBoxes {
  std::vector<Box> seg, run;
};

/// Everything one detection task (a tool slot, a thread, a soft body against bones or against
/// other soft bodies) writes: its contacts and the work lists of the pair tests it runs. One per
/// task, so tasks running on different workers never share a list.
struct ContactTaskScratch {
  // Output of the task, merged in task order.
  std::vector<physics::PointContact> contacts;
  std::vector<ConstraintEnd::Kind> kinds;  ///< obstacle kind per contact
  std::vector<ToolContact> touches;        ///< tool-bone touches (tool slot tasks)
  // Candidate lists of the pair tests (each cleared before use).
  std::vector<std::int32_t> tris, verts, cand, run_tris, owner;
  std::vector<std::pair<std::int32_t, std::int32_t>> edges_done;
  std::vector<Vec3> points;
  std::vector<std::array<double, 4>> weights;
  // Thread against a surface: per segment / node of the thread.
  std::vector<Nearest> seg_nearest;
  std::vector<std::vector<std::int32_t>> seg_tris;
  std::vector<std::int32_t> node_seg;
  std::vector<std::uint8_t> pierced, blocked_edge, blocked_node, near_node;
  // Nearest-triangle search over more candidates than fit on the stack.
  std::vector<double> box_d2, tri_d2;
  // Tool slot tasks: this step's and last step's primitives and their sweeps.
  std::vector<ToolPrimitive> prims, before;
  std::vector<Sweep> sweeps;
};

/// Work lists of the whole collision stage.
struct DetectScratch {
  std::vector<ThreadBoxes> thread_boxes;      ///< per thread, shared by both tool slots
  std::vector<ContactTaskScratch> tasks;      ///< per task, grown to the task count
  std::vector<physics::PointContact> merged;  ///< all tasks' contacts in task order
  std::vector<ConstraintEnd::Kind> merged_kinds;
  std::vector<std::size_t> order;  ///< sorted permutation of `merged`
  std::vector<std::uint64_t> key;  ///< packed leading sort fields per merged contact
};

}  // namespace arthrosim::collision
