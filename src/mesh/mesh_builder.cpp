#include "mesh_builder.h"

#include <algorithm>

namespace arthrosim::mesh::detail {

void NodeIndex::Build(const std::vector<std::int64_t>& tags, const Cursor& cur,
                      const std::string& field) {
  dense_.clear();
  sorted_.clear();
  if (tags.empty()) return;
  const auto [mn, mx] = std::minmax_element(tags.begin(), tags.end());
  const std::uint64_t span = static_cast<std::uint64_t>(*mx) - static_cast<std::uint64_t>(*mn);
  if (span <= 2 * tags.size() + 1024) {
    // Compact tags (the usual case): direct table.
    dense_min_ = *mn;
    dense_.assign(span + 1, -1);
    for (std::size_t i = 0; i < tags.size(); ++i) {
      std::int32_t& slot = dense_[static_cast<std::size_t>(tags[i] - dense_min_)];
      if (slot >= 0) cur.Fail(field, "duplicate node tag " + std::to_string(tags[i]));
      slot = static_cast<std::int32_t>(i);
    }
    return;
  }
  sorted_.reserve(tags.size());
  for (std::size_t i = 0; i < tags.size(); ++i) {
    sorted_.emplace_back(tags[i], static_cast<std::int32_t>(i));
  }
  std::sort(sorted_.begin(), sorted_.end());
  for (std::size_t i = 1; i < sorted_.size(); ++i) {
    if (sorted_[i].first == sorted_[i - 1].first) {
      cur.Fail(field, "duplicate node tag " + std::to_string(sorted_[i].first));
    }
  }
}

std::int32_t NodeIndex::Find(std::int64_t tag) const {
  if (!dense_.empty()) {
    if (tag < dense_min_) return -1;
    const std::uint64_t off =
        static_cast<std::uint64_t>(tag) - static_cast<std::uint64_t>(dense_min_);
    return off < dense_.size() ? dense_[off] : -1;
  }
  const auto it =
      std::lower_bound(sorted_.begin(), sorted_.end(), std::make_pair(tag, std::int32_t{-1}));
  return (it != sorted_.end() && it->first == tag) ? it->second : -1;
}

void MeshBuilder::AddElement(int dim, const std::int32_t* nodes, const std::vector<int>& physical,
                             std::int64_t dedupe_key) {
  const int first = physical.empty() ? 0 : physical.front();
  std::int32_t index = 0;
  if (dim == 3) {
    index = static_cast<std::int32_t>(tets_.size());
    tets_.push_back({nodes[0], nodes[1], nodes[2], nodes[3]});
    tet_phys_.push_back(first);
  } else if (dim == 2) {
    index = static_cast<std::int32_t>(tris_.size());
    tris_.push_back({nodes[0], nodes[1], nodes[2]});
    tri_phys_.push_back(first);
  } else {
    index = static_cast<std::int32_t>(edges_.size());
    edges_.push_back({nodes[0], nodes[1]});
    line_phys_.push_back(first);
  }
  if (dedupe_key >= 0) {
    DedupeEntry e{{dim, dedupe_key, -1, -1, -1, -1}, index};
    for (int k = 0; k <= dim; ++k) e.key[static_cast<std::size_t>(2 + k)] = nodes[k];
    dedupe_.push_back(e);
  }
  for (const int p : physical) {
    std::vector<std::int32_t>& members = groups_[{dim, p}];
    if (members.empty() || members.back() != index) members.push_back(index);
  }
}

void MeshBuilder::Dedupe() {
  if (dedupe_.empty()) return;
  std::sort(dedupe_.begin(), dedupe_.end(), [](const DedupeEntry& a, const DedupeEntry& b) {
    return a.key != b.key ? a.key < b.key : a.index < b.index;
  });
  // target[dim][i] = index of the first identical element (i itself if unique).
  std::vector<std::int32_t> target[4];
  target[1].resize(edges_.size());
  target[2].resize(tris_.size());
  target[3].resize(tets_.size());
  for (int d = 1; d <= 3; ++d) {
    for (std::size_t i = 0; i < target[d].size(); ++i) target[d][i] = static_cast<std::int32_t>(i);
  }
  bool any = false;
  for (std::size_t i = 1; i < dedupe_.size(); ++i) {
    std::size_t first = i - 1;
    while (i < dedupe_.size() && dedupe_[i].key == dedupe_[first].key) {
      const auto d = static_cast<std::size_t>(dedupe_[i].key[0]);
      target[d][static_cast<std::size_t>(dedupe_[i].index)] = dedupe_[first].index;
      any = true;
      ++i;
    }
  }
  dedupe_.clear();
  if (!any) return;
  // Compact each dimension keeping first occurrences in file order.
  std::vector<std::int32_t> renum[4];
  auto compact = [&](auto& elems, std::vector<int>& phys, int d) {
    renum[d].assign(elems.size(), -1);
    std::size_t out = 0;
    for (std::size_t i = 0; i < elems.size(); ++i) {
      if (target[d][i] != static_cast<std::int32_t>(i)) continue;
      renum[d][i] = static_cast<std::int32_t>(out);
      elems[out] = elems[i];
      phys[out] = phys[i];
      ++out;
    }
    for (std::size_t i = 0; i < elems.size(); ++i) {
      renum[d][i] = renum[d][static_cast<std::size_t>(target[d][i])];
    }
    elems.resize(out);
    phys.resize(out);
  };
  compact(edges_, line_phys_, 1);
  compact(tris_, tri_phys_, 2);
  compact(tets_, tet_phys_, 3);
  for (auto& [key, members] : groups_) {
    if (key.first < 1 || key.first > 3) continue;
    for (std::int32_t& m : members) m = renum[key.first][static_cast<std::size_t>(m)];
  }
}

MeshData MeshBuilder::Finish(std::string format) {
  Dedupe();
  MeshData d;
  d.format = std::move(format);
  const Eigen::Index n = static_cast<Eigen::Index>(tags_.size());
  Points nodes(3, n);
  for (Eigen::Index i = 0; i < n; ++i) {
    for (int k = 0; k < 3; ++k) nodes(k, i) = xyz_[static_cast<std::size_t>(3 * i + k)];
  }
  d.volume.nodes = nodes;
  d.surface.nodes = nodes;
  d.lines.nodes = std::move(nodes);
  d.volume.tets = std::move(tets_);
  d.surface.tris = std::move(tris_);
  d.lines.edges = std::move(edges_);
  d.tet_physical = std::move(tet_phys_);
  d.tri_physical = std::move(tri_phys_);
  d.line_physical = std::move(line_phys_);
  d.node_tags = std::move(tags_);
  for (auto& [key, members] : groups_) {
    if (key.first < 1 || key.first > 3) continue;
    PhysicalGroup g;
    g.dim = key.first;
    g.tag = key.second;
    const auto it = names_.find(key);
    if (it != names_.end()) g.name = it->second;
    std::sort(members.begin(), members.end());
    members.erase(std::unique(members.begin(), members.end()), members.end());
    g.elements = std::move(members);
    d.groups.push_back(std::move(g));
  }
  d.warnings = std::move(warnings_);
  *this = MeshBuilder();
  return d;
}

}  // namespace arthrosim::mesh::detail
