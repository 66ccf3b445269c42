#include "arthrosim/mesh/surface.h"

#include <algorithm>
#include <stdexcept>
#include <string>

namespace arthrosim::mesh {
namespace {

std::array<std::int32_t, 3> SortedKey(const Tri& f) {
  std::array<std::int32_t, 3> k = f;
  std::sort(k.begin(), k.end());
  return k;
}

}  // namespace

Tri TetFace(const Tet& t, int f) {
  const auto& l = kTetFaces[static_cast<std::size_t>(f)];
  return {t[l[0]], t[l[1]], t[l[2]]};
}

std::vector<BoundaryFace> ExtractBoundary(const std::vector<Tet>& tets,
                                          const std::vector<std::uint8_t>& alive) {
  struct Entry {
    std::array<std::int32_t, 3> key;
    std::int32_t tet;
    std::int8_t face;
  };
  std::vector<Entry> all;
  all.reserve(tets.size() * 4);
  for (std::size_t t = 0; t < tets.size(); ++t) {
    if (!alive.empty() && !alive[t]) continue;
    for (int f = 0; f < 4; ++f) {
      all.push_back({SortedKey(TetFace(tets[t], f)), static_cast<std::int32_t>(t),
                     static_cast<std::int8_t>(f)});
    }
  }
  // Total order (key, tet, face): equal keys become adjacent.
  std::sort(all.begin(), all.end(), [](const Entry& a, const Entry& b) {
    if (a.key != b.key) return a.key < b.key;
    if (a.tet != b.tet) return a.tet < b.tet;
    return a.face < b.face;
  });
  std::vector<BoundaryFace> out;
  for (std::size_t i = 0; i < all.size();) {
    std::size_t j = i + 1;
    while (j < all.size() && all[j].key == all[i].key) ++j;
    if (j - i == 1) {
      out.push_back({TetFace(tets[static_cast<std::size_t>(all[i].tet)], all[i].face), all[i].tet,
                     all[i].face});
    }
    i = j;
  }
  std::sort(out.begin(), out.end(), [](const BoundaryFace& a, const BoundaryFace& b) {
    return a.tet != b.tet ? a.tet < b.tet : a.face < b.face;
  });
  return out;
}

TriMesh BoundaryTriMesh(const TetMesh& m, const std::vector<std::uint8_t>& alive) {
  TriMesh s;
  s.nodes = m.nodes;
  const std::vector<BoundaryFace> faces = ExtractBoundary(m.tets, alive);
  s.tris.reserve(faces.size());
  for (const BoundaryFace& f : faces) s.tris.push_back(f.nodes);
  return s;
}

BoundaryTracker::BoundaryTracker(std::vector<Tet> tets, const std::vector<std::uint8_t>& alive)
    : tets_(std::move(tets)) {
  if (!alive.empty() && alive.size() != tets_.size()) {
    throw std::invalid_argument("BoundaryTracker: alive mask has " + std::to_string(alive.size()) +
                                " entries for " + std::to_string(tets_.size()) + " tets");
  }
  // Bulk build: sort all (key, tet, face) once, number faces in key order, then insert keys and
  // boundary entries with end() hints (sorted input makes each insert O(1) amortised).
  struct Entry {
    FaceKey key;
    Incidence inc;
  };
  std::vector<Entry> all;
  all.reserve(tets_.size() * 4);
  for (std::size_t t = 0; t < tets_.size(); ++t) {
    for (int f = 0; f < 4; ++f) {
      all.push_back({SortedKey(TetFace(tets_[t], f)),
                     {static_cast<std::int32_t>(t), static_cast<std::int8_t>(f)}});
    }
  }
  std::sort(all.begin(), all.end(), [](const Entry& a, const Entry& b) {
    return a.key != b.key ? a.key < b.key : a.inc < b.inc;
  });
  alive_.assign(tets_.size(), 0);
  for (std::size_t t = 0; t < tets_.size(); ++t) alive_[t] = alive.empty() || alive[t] ? 1 : 0;
  tet_faces_.assign(tets_.size(), {-1, -1, -1, -1});
  for (std::size_t i = 0; i < all.size(); ++i) {
    if (i == 0 || all[i].key != all[i - 1].key) {
      face_ids_.emplace_hint(face_ids_.end(), all[i].key,
                             static_cast<std::int32_t>(incidences_.size()));
      incidences_.emplace_back();
    }
    const auto id = static_cast<std::int32_t>(incidences_.size() - 1);
    const Incidence inc = all[i].inc;
    tet_faces_[static_cast<std::size_t>(inc.first)][static_cast<std::size_t>(inc.second)] = id;
    if (alive_[static_cast<std::size_t>(inc.first)]) incidences_.back().push_back(inc);
  }
  for (std::size_t t = 0; t < tets_.size(); ++t) {
    for (int f = 0; f < 4; ++f) {
      const auto& inc =
          incidences_[static_cast<std::size_t>(tet_faces_[t][static_cast<std::size_t>(f)])];
      if (inc.size() == 1 && inc.front().first == static_cast<std::int32_t>(t)) {
        boundary_.emplace_hint(boundary_.end(), inc.front());
      }
    }
  }
}

std::int32_t BoundaryTracker::FaceId(const FaceKey& key) {
  const auto [it, fresh] = face_ids_.emplace(key, static_cast<std::int32_t>(incidences_.size()));
  if (fresh) incidences_.emplace_back();
  return it->second;
}

void BoundaryTracker::Attach(std::int32_t t) {
  alive_[static_cast<std::size_t>(t)] = 1;
  for (int f = 0; f < 4; ++f) {
    const std::int32_t id = tet_faces_[static_cast<std::size_t>(t)][static_cast<std::size_t>(f)];
    std::vector<Incidence>& inc = incidences_[static_cast<std::size_t>(id)];
    const Incidence me{t, static_cast<std::int8_t>(f)};
    inc.insert(std::lower_bound(inc.begin(), inc.end(), me), me);
    Refresh(id);
  }
}

void BoundaryTracker::Detach(std::int32_t t) {
  alive_[static_cast<std::size_t>(t)] = 0;
  for (int f = 0; f < 4; ++f) {
    const std::int32_t id = tet_faces_[static_cast<std::size_t>(t)][static_cast<std::size_t>(f)];
    std::vector<Incidence>& inc = incidences_[static_cast<std::size_t>(id)];
    const Incidence me{t, static_cast<std::int8_t>(f)};
    boundary_.erase(me);
    const auto pos = std::lower_bound(inc.begin(), inc.end(), me);
    if (pos != inc.end() && *pos == me) inc.erase(pos);
    Refresh(id);
  }
}

void BoundaryTracker::Refresh(std::int32_t face) {
  const std::vector<Incidence>& inc = incidences_[static_cast<std::size_t>(face)];
  // A face is boundary iff exactly one alive tet has it.
  for (const Incidence& i : inc) boundary_.erase(i);
  if (inc.size() == 1) boundary_.insert(inc.front());
}

void BoundaryTracker::RemoveTet(std::int32_t t) {
  if (t < 0 || static_cast<std::size_t>(t) >= tets_.size()) {
    throw std::out_of_range("BoundaryTracker::RemoveTet: tet " + std::to_string(t) +
                            " out of range [0, " + std::to_string(tets_.size()) + ")");
  }
  if (alive_[static_cast<std::size_t>(t)]) Detach(t);
}

void BoundaryTracker::ReviveTet(std::int32_t t) {
  if (t < 0 || static_cast<std::size_t>(t) >= tets_.size()) {
    throw std::out_of_range("BoundaryTracker::ReviveTet: tet " + std::to_string(t) +
                            " out of range [0, " + std::to_string(tets_.size()) + ")");
  }
  if (!alive_[static_cast<std::size_t>(t)]) Attach(t);
}

std::int32_t BoundaryTracker::AddTet(const Tet& tet) {
  const auto t = static_cast<std::int32_t>(tets_.size());
  tets_.push_back(tet);
  alive_.push_back(0);
  std::array<std::int32_t, 4> ids{};
  for (int f = 0; f < 4; ++f) ids[static_cast<std::size_t>(f)] = FaceId(SortedKey(TetFace(tet, f)));
  tet_faces_.push_back(ids);
  Attach(t);
  return t;
}

std::vector<BoundaryFace> BoundaryTracker::Faces() const {
  std::vector<BoundaryFace> out;
  out.reserve(boundary_.size());
  for (const Incidence& i : boundary_) {
    out.push_back({TetFace(tets_[static_cast<std::size_t>(i.first)], i.second), i.first, i.second});
  }
  return out;
}

}  // namespace arthrosim::mesh
