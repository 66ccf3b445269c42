#include "arthrosim/scoring/sight.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "arthrosim/scoring/run_data.h"

namespace arthrosim::scoring {
namespace {

// Whether the segment p + s d, s in [s0, s1], meets the box (slab test). Conservative for a
// box tree: true for a box whenever it is true for a box inside it.
bool SegmentMeetsBox(const Vec3& p, const Vec3& d, double s0, double s1, const collision::Box& b) {
  for (int a = 0; a < 3; ++a) {
    if (std::abs(d[a]) < 1e-300) {
      if (p[a] < b.lo[a] || p[a] > b.hi[a]) return false;
      continue;
    }
    double t0 = (b.lo[a] - p[a]) / d[a], t1 = (b.hi[a] - p[a]) / d[a];
    if (t0 > t1) std::swap(t0, t1);
    s0 = std::max(s0, t0);
    s1 = std::min(s1, t1);
    if (s0 > s1) return false;
  }
  return true;
}

// Whether p + s d, s in [s0, s1], crosses triangle (a, b, c) (Moeller-Trumbore; a segment in
// the triangle's plane does not cross it; edges and corners count).
bool SegmentCrossesTriangle(const Vec3& p, const Vec3& d, double s0, double s1, const Vec3& a,
                            const Vec3& b, const Vec3& c) {
  const Vec3 e1 = b - a, e2 = c - a;
  const Vec3 h = d.cross(e2);
  const double det = e1.dot(h);
  if (std::abs(det) < 1e-12 * e1.norm() * e2.norm() * d.norm()) return false;
  const double inv = 1.0 / det;
  const Vec3 q = p - a;
  const double u = q.dot(h) * inv;
  if (u < 0.0 || u > 1.0) return false;
  const Vec3 r = q.cross(e1);
  const double v = d.dot(r) * inv;
  if (v < 0.0 || u + v > 1.0) return false;
  const double s = e2.dot(r) * inv;
  return s >= s0 && s <= s1;
}

// Positions of the nodes `ids` (all nodes if empty) of `nodes`.
void Gather(const Points& nodes, const std::vector<std::int32_t>& ids, std::vector<Vec3>* out) {
  if (ids.empty()) {
    out->resize(static_cast<std::size_t>(nodes.cols()));
    for (Eigen::Index n = 0; n < nodes.cols(); ++n)
      (*out)[static_cast<std::size_t>(n)] = nodes.col(n);
    return;
  }
  out->resize(ids.size());
  for (std::size_t k = 0; k < ids.size(); ++k) (*out)[k] = nodes.col(ids[k]);
}

}  // namespace

void SightBlockers::Update(const Model& model, const State& state) {
  if (state.soft_bodies.size() != model.soft_bodies.size() ||
      state.bones.size() != model.bones.size())
    throw std::invalid_argument("SightBlockers: State body counts do not match the Model");
  soft_.resize(state.soft_bodies.size());
  for (std::size_t i = 0; i < soft_.size(); ++i) {
    const SoftBodyState& s = state.soft_bodies[i];
    Body& b = soft_[i];
    if (!b.built || b.tets != s.tets || b.alive != s.tet_alive ||
        b.nodes != static_cast<std::size_t>(s.x.cols())) {
      b.tets = s.tets;
      b.alive = s.tet_alive;
      b.nodes = static_cast<std::size_t>(s.x.cols());
      // the surface in a local numbering of the nodes it uses (as the collision world does)
      collision::Surface surface =
          collision::MakeSurface(collision::BoundaryTriangles(s.tets, s.tet_alive));
      for (const std::int32_t n : surface.vertices)
        if (n < 0 || n >= s.x.cols())
          throw std::invalid_argument("SightBlockers: soft body '" + model.soft_bodies[i].name +
                                      "' has a tet on node " + std::to_string(n) + " of " +
                                      std::to_string(s.x.cols()));
      b.node_ids = std::move(surface.vertices);
      b.triangles = std::move(surface.local_tris);
      Gather(s.x, b.node_ids, &b.vertices);
      b.tree = collision::TriangleBvh{};
      if (!b.triangles.empty()) b.tree.Build(b.vertices, b.triangles);
      b.built = true;
      continue;
    }
    Gather(s.x, b.node_ids, &b.vertices);
    if (!b.triangles.empty()) b.tree.Refit(b.vertices);
  }
  bones_.resize(state.bones.size());
  for (std::size_t i = 0; i < bones_.size(); ++i) {
    const mesh::TriMesh& surface = state.bones[i].surface;
    Body& b = bones_[i];
    const std::size_t nodes = static_cast<std::size_t>(surface.nodes.cols());
    if (b.built && b.revision == state.bones[i].revision && b.nodes == nodes &&
        b.tris == surface.tris.size())
      continue;
    b.revision = state.bones[i].revision;
    b.nodes = nodes;
    b.tris = surface.tris.size();
    for (const mesh::Tri& t : surface.tris)
      for (const std::int32_t n : t)
        if (n < 0 || static_cast<std::size_t>(n) >= nodes)
          throw std::invalid_argument("SightBlockers: bone '" + model.bones[i].name +
                                      "' has a triangle on node " + std::to_string(n) + " of " +
                                      std::to_string(nodes));
    Gather(surface.nodes, {}, &b.vertices);
    b.triangles = surface.tris;
    b.tree = collision::TriangleBvh{};
    if (!b.triangles.empty()) b.tree.Build(b.vertices, b.triangles);
    b.built = true;
  }
}

bool SightBlockers::Blocked(const Vec3& from, const Vec3& to, double skip_from_mm,
                            double skip_to_mm) const {
  const Vec3 d = to - from;
  const double length = d.norm();
  if (!(length > 0.0)) return false;
  const double s0 = std::max(0.0, skip_from_mm) / length;
  const double s1 = 1.0 - std::max(0.0, skip_to_mm) / length;
  if (!(s0 < s1)) return false;
  std::vector<std::int32_t> hits;
  for (const std::vector<Body>* group : {&soft_, &bones_}) {
    for (const Body& b : *group) {
      if (b.triangles.empty()) continue;
      hits.clear();
      b.tree.QueryIf(
          [&](const collision::Box& box) { return SegmentMeetsBox(from, d, s0, s1, box); }, &hits);
      for (const std::int32_t t : hits) {
        const mesh::Tri& tri = b.triangles[static_cast<std::size_t>(t)];
        if (SegmentCrossesTriangle(from, d, s0, s1, b.vertices[tri[0]], b.vertices[tri[1]],
                                   b.vertices[tri[2]]))
          return true;
      }
    }
  }
  return false;
}

bool TipVisible(const Model& model, const CameraState& camera, const Vec3& tip_mm,
                double tip_margin_mm, const SightBlockers& blockers) {
  if (!PointInView(model, camera, tip_mm)) return false;
  return !blockers.Blocked(camera.pose.position_mm, tip_mm, model.camera.near_mm, tip_margin_mm);
}

}  // namespace arthrosim::scoring
