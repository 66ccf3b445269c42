#pragma once
// Internal: collects nodes and elements while a reader parses, then assembles a MeshData with
// the shared node array, per-element physical tags and (dim, tag)-ordered groups.
#include <array>
#include <cstdint>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "arthrosim/mesh/mesh_io.h"
#include "cursor.h"

namespace arthrosim::mesh::detail {

/// Maps file node tags (any int64, possibly sparse) to dense 0-based indices in file order.
class NodeIndex {
 public:
  /// Builds the map; duplicate tags are reported through `cur` (line of the current token).
  void Build(const std::vector<std::int64_t>& tags, const Cursor& cur, const std::string& field);
  /// Dense index of `tag`, or -1 if the file declared no such node.
  std::int32_t Find(std::int64_t tag) const;

 private:
  std::int64_t dense_min_ = 0;
  std::vector<std::int32_t> dense_;                            // used when tags are compact
  std::vector<std::pair<std::int64_t, std::int32_t>> sorted_;  // otherwise binary search
};

class MeshBuilder {
 public:
  /// Appends a node; coordinates must already be checked finite.
  void AddNode(std::int64_t tag, double x, double y, double z) {
    tags_.push_back(tag);
    xyz_.push_back(x);
    xyz_.push_back(y);
    xyz_.push_back(z);
  }
  std::int64_t num_nodes() const { return static_cast<std::int64_t>(tags_.size()); }
  const std::vector<std::int64_t>& node_tags() const { return tags_; }

  /// Appends an element of dimension 1..3 (2, 3 or 4 dense node indices) with its physical tags.
  /// `dedupe_key` >= 0 merges a repeat of the same (dim, key, nodes) into the earlier element
  /// (MSH 2 writes an element once per physical group it belongs to).
  void AddElement(int dim, const std::int32_t* nodes, const std::vector<int>& physical,
                  std::int64_t dedupe_key = -1);
  /// Records a physical name for (dim, tag).
  void SetName(int dim, int tag, std::string name) { names_[{dim, tag}] = std::move(name); }
  /// Ensures a (possibly empty) group exists for (dim, tag).
  void TouchGroup(int dim, int tag) { groups_[{dim, tag}]; }
  void Warn(std::string w) { warnings_.push_back(std::move(w)); }

  /// Builds the result and leaves the builder empty.
  MeshData Finish(std::string format);

 private:
  std::vector<std::int64_t> tags_;
  std::vector<double> xyz_;
  std::vector<Tet> tets_;
  std::vector<Tri> tris_;
  std::vector<Edge> edges_;
  std::vector<int> tet_phys_, tri_phys_, line_phys_;
  std::map<std::pair<int, int>, std::vector<std::int32_t>> groups_;
  std::map<std::pair<int, int>, std::string> names_;
  struct DedupeEntry {
    std::array<std::int64_t, 6> key;  // dim, entity, nodes (padded with -1)
    std::int32_t index;               // element index within its dimension
  };
  std::vector<DedupeEntry> dedupe_;  // resolved once in Finish (sorting beats a map per element)
  void Dedupe();
  std::vector<std::string> warnings_;
};

/// Gmsh .msh (2.2 ASCII, 4.1 ASCII/binary).
MeshData ReadMsh(Cursor& cur);
/// Legacy VTK unstructured grid, ASCII.
MeshData ReadVtk(Cursor& cur);
/// Wavefront OBJ.
MeshData ReadObj(Cursor& cur);
/// STL, ASCII or binary.
MeshData ReadStl(Cursor& cur);

}  // namespace arthrosim::mesh::detail
