#include "arthrosim/scoring/sight.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "arthrosim/mesh/surface.h"
#include "arthrosim/scoring/run_data.h"

namespace arthrosim::scoring {
namespace {

constexpr std::size_t kChunk = 32;  // triangles per box

// Whether the segment p + s d, s in [s0, s1], meets the box [lo, hi] (slab test).
bool SegmentMeetsBox(const Vec3& p, const Vec3& d, double s0, double s1, const Vec3& lo,
                     const Vec3& hi) {
  for (int a = 0; a < 3; ++a) {
    if (std::abs(d[a]) < 1e-300) {
      if (p[a] < lo[a] || p[a] > hi[a]) return false;
      continue;
    }
    double t0 = (lo[a] - p[a]) / d[a], t1 = (hi[a] - p[a]) / d[a];
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

// The columns of `nodes` as points.
void Copy(const Points& nodes, std::vector<Vec3>* out) {
  out->resize(static_cast<std::size_t>(nodes.cols()));
  for (Eigen::Index n = 0; n < nodes.cols(); ++n)
    (*out)[static_cast<std::size_t>(n)] = nodes.col(n);
}

}  // namespace

void SightBlockers::FitChunks(Body* b) {
  const std::size_t chunks = (b->triangles.size() + kChunk - 1) / kChunk;
  b->chunk_boxes.resize(chunks);
  for (std::size_t c = 0; c < chunks; ++c) {
    Box box{Vec3::Constant(1e300), Vec3::Constant(-1e300)};
    const std::size_t end = std::min(b->triangles.size(), (c + 1) * kChunk);
    for (std::size_t t = c * kChunk; t < end; ++t) {
      for (const std::int32_t n : b->triangles[t]) {
        box.lo = box.lo.cwiseMin(b->vertices[static_cast<std::size_t>(n)]);
        box.hi = box.hi.cwiseMax(b->vertices[static_cast<std::size_t>(n)]);
      }
    }
    b->chunk_boxes[c] = box;
  }
}

void SightBlockers::Update(const Model& model, const State& state) {
  if (state.soft_bodies.size() != model.soft_bodies.size() ||
      state.bones.size() != model.bones.size())
    throw std::invalid_argument("SightBlockers: State body counts do not match the Model");
  auto check = [](const Body& b, const std::string& what) {
    for (const mesh::Tri& t : b.triangles)
      for (const std::int32_t n : t)
        if (n < 0 || static_cast<std::size_t>(n) >= b.vertices.size())
          throw std::invalid_argument("SightBlockers: " + what + " has a face on node " +
                                      std::to_string(n) + " of " +
                                      std::to_string(b.vertices.size()));
  };
  soft_.resize(state.soft_bodies.size());
  for (std::size_t i = 0; i < soft_.size(); ++i) {
    const SoftBodyState& s = state.soft_bodies[i];
    Body& b = soft_[i];
    Copy(s.x, &b.vertices);
    if (!b.built || b.tets != s.tets || b.alive != s.tet_alive || b.nodes != b.vertices.size()) {
      b.tets = s.tets;
      b.alive = s.tet_alive;
      b.nodes = b.vertices.size();
      b.triangles.clear();
      for (const mesh::BoundaryFace& f : mesh::ExtractBoundary(s.tets, s.tet_alive))
        b.triangles.push_back(f.nodes);
      check(b, "soft body '" + model.soft_bodies[i].name + "'");
      b.built = true;
    }
    FitChunks(&b);
  }
  bones_.resize(state.bones.size());
  for (std::size_t i = 0; i < bones_.size(); ++i) {
    const mesh::TriMesh& surface = state.bones[i].surface;
    Body& b = bones_[i];
    const auto nodes = static_cast<std::size_t>(surface.nodes.cols());
    if (b.built && b.revision == state.bones[i].revision && b.nodes == nodes &&
        b.tris == surface.tris.size())
      continue;
    b.revision = state.bones[i].revision;
    b.nodes = nodes;
    b.tris = surface.tris.size();
    Copy(surface.nodes, &b.vertices);
    b.triangles = surface.tris;
    check(b, "bone '" + model.bones[i].name + "'");
    FitChunks(&b);
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
  for (const std::vector<Body>* group : {&soft_, &bones_}) {
    for (const Body& b : *group) {
      for (std::size_t c = 0; c < b.chunk_boxes.size(); ++c) {
        if (!SegmentMeetsBox(from, d, s0, s1, b.chunk_boxes[c].lo, b.chunk_boxes[c].hi)) continue;
        const std::size_t end = std::min(b.triangles.size(), (c + 1) * kChunk);
        for (std::size_t t = c * kChunk; t < end; ++t) {
          const mesh::Tri& tri = b.triangles[t];
          if (SegmentCrossesTriangle(from, d, s0, s1, b.vertices[static_cast<std::size_t>(tri[0])],
                                     b.vertices[static_cast<std::size_t>(tri[1])],
                                     b.vertices[static_cast<std::size_t>(tri[2])]))
            return true;
        }
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

bool FrameSight::Sees(const Vec3& point_mm, double margin_mm) {
  if (!PointInView(*model_, state_->camera, point_mm)) return false;
  if (!updated_) blockers_->Update(*model_, *state_);
  updated_ = true;
  return TipVisible(*model_, state_->camera, point_mm, margin_mm, *blockers_);
}

bool FrameSight::SeesLandmark(int index) {
  if (index < 0 || index >= static_cast<int>(model_->landmarks.size())) return false;
  return Sees(model_->landmarks[static_cast<std::size_t>(index)].position_mm,
              kLandmarkSightMarginMm);
}

}  // namespace arthrosim::scoring
