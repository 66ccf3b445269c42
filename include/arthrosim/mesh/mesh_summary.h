#pragma once
// A short description of a mesh file's content, for `arthrosim info`.
#include <cstdint>
#include <string>
#include <vector>

#include "arthrosim/core/types.h"
#include "arthrosim/mesh/mesh_io.h"

namespace arthrosim::mesh {

struct GroupSummary {
  int dim = 0;
  int tag = 0;
  std::string name;
  std::int64_t num_elements = 0;
};

struct MeshSummary {
  std::string format;
  std::int64_t num_nodes = 0, num_tets = 0, num_tris = 0, num_lines = 0;
  Vec3 bbox_min_mm = Vec3::Zero();  ///< component-wise minimum of all nodes (0 if none)
  Vec3 bbox_max_mm = Vec3::Zero();
  double tet_volume_mm3 = 0;            ///< sum of signed tet volumes as stored
  std::int64_t num_inverted_tets = 0;   ///< negative signed volume (OrientAndCheck would fix)
  std::int64_t num_boundary_faces = 0;  ///< of the tets (0 without tets)
  std::vector<GroupSummary> groups;
  std::vector<std::string> warnings;
};

/// Counts, bounding box (mm), volume and groups of `d`. Does not modify or validate indices
/// beyond what the readers guarantee.
MeshSummary Summarize(const MeshData& d);
/// Human-readable multi-line text of a summary (one fact per line, "key: value").
std::string FormatSummary(const MeshSummary& s);

}  // namespace arthrosim::mesh
