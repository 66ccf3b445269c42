#pragma once
// Shared by the files of the collision stage (not installed): the geometric tests, the contact
// builder every pair test writes through, and the pair tests by kind, which Detect
// (contact_generation.cpp) runs as independent tasks:
//   contact_geometry.cpp  nearest triangle, sweeps against a target
//   contact_tool.cpp      tool slot: sweeps, against tissue, tissue volume, threads, bone
//   contact_thread.cpp    thread against tissue (both sides) and bone
//   contact_tissue.cpp    soft tissue against bone, bone tips, other soft tissue
//   collision_world.cpp   SyncWorld: surfaces, trees, join flags, salient bone vertices
#include <algorithm>
#include <array>
#include <cstdint>
#include <vector>

#include "arthrosim/collision/contact_generation.h"
#include "arthrosim/collision/contact_scratch.h"

namespace arthrosim::collision::internal {

using Kind = ConstraintEnd::Kind;
using physics::PointContact;

// Below this separation (mm) a closest-point direction is numerically meaningless; the contact
// normal then comes from the surface instead.
constexpr double kMinDirection = 1e-9;

// Extra search radius (mm) beyond the contact reach of the soft-soft and bone tip-soft searches:
// what a point found that far out may move (with the surface's drift) before it is searched again.
constexpr double kFarSlack = 2.0;

// Rounding allowance (mm) of the out-of-reach bounds: distances are computed to ~1e-12 mm.
constexpr double kCertSlack = 1e-6;

// Culling tests are conservative by this much (mm), so rounding never drops a true candidate.
constexpr double kCullSlack = 1e-6;

// Thread segments per run box (ThreadBoxes::run).
constexpr std::size_t kRun = 8;

// ---- small geometric helpers ----------------------------------------------------------------

inline Vec3 SafeNormalized(const Vec3& v, const Vec3& fallback) {
  const double n = v.norm();
  return n > kMinDirection ? Vec3(v / n) : fallback;
}

// Positions of the listed nodes, in list order.
void FillPositions(const Points& x, const std::vector<std::int32_t>& ids, std::vector<Vec3>* out);

// Unit normal of a triangle given in indices into p (right-hand rule).
inline Vec3 FaceNormal(const std::vector<Vec3>& p, const mesh::Tri& t) {
  return SafeNormalized((p[t[1]] - p[t[0]]).cross(p[t[2]] - p[t[0]]), Vec3::UnitZ());
}

// Unit vertex normal of local vertex v: the normalised area-weighted sum of its triangles' normals.
Vec3 VertexNormal(const Surface& s, const std::vector<Vec3>& p, std::int32_t v);

inline Simplex LocalTriangle(const std::vector<Vec3>& p, const mesh::Tri& t) {
  return TriangleSimplex(p[t[0]], p[t[1]], p[t[2]]);
}

inline Box SimplexBox(const Simplex& s) {
  Box b;
  for (int i = 0; i < s.n; ++i) b.Add(s.v[i]);
  return b;
}

// Squared distance between two boxes (0 if they overlap), mm^2: a lower bound of the distance
// of any two points in them.
inline double BoxDist2(const Box& a, const Box& b) {
  double d2 = 0;
  for (int k = 0; k < 3; ++k) {
    const double g = std::max(std::max(a.lo[k] - b.hi[k], b.lo[k] - a.hi[k]), 0.0);
    d2 += g * g;
  }
  return d2;
}

// True if box a grown by m overlaps box b.
inline bool NearBoxes(const Box& a, double m, const Box& b) {
  return (a.lo.array() - m <= b.hi.array()).all() && (b.lo.array() <= a.hi.array() + m).all();
}

// Conservative: may some point of box b lie within `reach` of the simplex `core` (whose box is
// core_box)? Box test, then the ball around b's centre through its corners against the core.
inline bool BoxNearCore(const Box& core_box, const Simplex& core, double reach, const Box& b) {
  if (!NearBoxes(core_box, reach + kCullSlack, b)) return false;
  const Vec3 c = 0.5 * (b.lo + b.hi);
  const double lim = reach + 0.5 * (b.hi - b.lo).norm() + kCullSlack;
  return Closest(PointSimplex(c), core).dist2 <= lim * lim;
}

// Conservative: false only when a triangle's plane separates the other simplex from it by more
// than `reach` (then no point pair is within reach). Cheap next to an exact triangle test.
bool PlanesAllowReach(const Simplex& a, const Simplex& b, double reach);

// Support function of a simplex: max over its points of n . x, mm.
inline double Support(const Simplex& s, const Vec3& n) {
  double h = n.dot(s.v[0]);
  for (int i = 1; i < s.n; ++i) h = std::max(h, n.dot(s.v[i]));
  return h;
}

// ---- nearest triangle and sweeps ------------------------------------------------------------

// The nearest triangle among the candidates, as if each were tested in ascending order (the
// first of exactly equal minima wins), and the pseudo-normal summed over the ties in ascending
// order; see contact_geometry.cpp. `scratch` holds the work lists when there are more
// candidates than fit on the stack.
Nearest NearestOnSurface(const Simplex& q, const Box& qbox, const std::vector<std::int32_t>& cand,
                         const TriangleBvh& bvh, const std::vector<Vec3>& p,
                         const std::vector<mesh::Tri>& tris, ContactTaskScratch* scratch,
                         std::int32_t hint = -1);

// Conservative: may some point of box b come within `reach` of the swept core at some substep?
inline bool SweepNear(const Sweep& sw, double reach, const Box& b) {
  if (!NearBoxes(sw.box, reach + kCullSlack, b)) return false;
  for (std::size_t s = 0; s < sw.sub.size(); ++s) {
    if (BoxNearCore(sw.sub_box[s], sw.sub[s], reach, b)) return true;
  }
  return false;
}

// First substep at which the target (whose box is target_box) comes within `reach` of the swept
// core, -1 if none; `last`, if given, is the caller's Closest(sw.sub.back(), target).
int FirstTouch(const Sweep& sw, double reach, const Simplex& target, const Box& target_box,
               ClosestPair* at, const ClosestPair* last = nullptr);

// Conservative: false when no substep can bring the target within reach (cheap tests only).
bool MayTouch(const Sweep& sw, double reach, const Simplex& target, const Box& target_box);

// Closest(sw.sub.back(), target), reusing the touch when it happened at the last substep.
inline ClosestPair CurrentClosest(const Sweep& sw, int touched_at, const ClosestPair& touch,
                                  const Simplex& target) {
  if (touched_at + 1 == static_cast<int>(sw.sub.size())) return touch;
  return Closest(sw.sub.back(), target);
}

// ---- the contact builder --------------------------------------------------------------------

// What every pair test reads (model, state, parameters) and writes (its task's scratch).
struct ContactBuilder {
  const Model& model;
  const State& state;
  const CollisionParams& params;
  ContactTaskScratch& scratch;  // contacts, kinds and the work lists of this task

  void Add(const PointContact& c, Kind obstacle) {
    scratch.contacts.push_back(c);
    scratch.kinds.push_back(obstacle);
  }

  bool SoftFixed(int body, std::int32_t node) const {
    const auto& f = model.soft_bodies[body].fixed_nodes;
    return std::binary_search(f.begin(), f.end(), node);
  }
  // Nodes past a soft body's initial mesh were made by split-mode cuts (instruments/
  // tet_split.cpp: edge points on the cut plane and the copies that part its two sides): they
  // lie on a cut surface.
  bool MadeByCut(int body, std::int32_t node) const {
    return node >= model.soft_bodies[body].rest_mesh.nodes.cols();
  }
  bool ThreadFixed(int thread, std::int32_t node) const {
    const auto& f = model.threads[thread].fixed_nodes;
    return std::find(f.begin(), f.end(), node) != f.end();
  }
  bool ThreadAlive(int thread, std::int32_t node) const {
    const auto& a = state.threads[thread].node_alive;
    return node < static_cast<std::int32_t>(a.size()) && a[node] != 0;
  }
};

// Contact on a thread segment point with parameter u (0 = node a, 1 = node b).
PointContact ThreadPoint(int thread, std::int32_t a, std::int32_t b, double u);

// Contact on the point of soft body `body`'s surface triangle `tri` at barycentric weights `w`,
// held on the side `normal` points to of the plane normal . x = offset_mm, against obstacle
// `obstacle_id`.
PointContact SoftTrianglePoint(int body, const mesh::Tri& tri, const std::array<double, 3>& w,
                               const Vec3& normal, double offset_mm, double stiffness_n_per_mm,
                               int obstacle_id);

// ---- pair tests by kind (one task each in Detect) -------------------------------------------

// Thread segment boxes of one thread for the tool tests (made once per step).
void MakeThreadBoxes(const Model& model, const State& state, int thread, ThreadBoxes* out);

// Tool slot `slot` swept from prev_tools[slot] to state.tools[slot] against every soft body
// (surface and, for a sharp point, volume), thread and bone; tool-bone reactions go to
// out->bone_force_n[slot] and out->substeps[slot], touches to builder->scratch.touches.
void DetectToolSlot(ContactBuilder* builder, int slot,
                    const std::array<ToolState, kToolSlots>& prev_tools, CollisionWorld* world,
                    const std::vector<ThreadBoxes>& thread_boxes, CollisionOutput* out);

// One thread against every soft surface (both sides) and bone (thread side).
void DetectThread(ContactBuilder* builder, int thread, CollisionWorld* world);

// Soft body `body` against every bone: its surface vertices against the bone surface, and the
// bone's salient vertices against its triangles (if params.bone_tip_contacts).
void DetectTissueBones(ContactBuilder* builder, int body, CollisionWorld* world);

// Soft body `body`'s surface vertices against every other soft body's triangles.
void DetectTissueTissue(ContactBuilder* builder, int body, CollisionWorld* world);

// ---- near-bone candidate cache (tissue and threads against bone) -----------------------------

// Bone triangles whose box overlaps `query`, ascending, through entry i of *cache.
void NearBoneTriangles(const CollisionWorld::BoneEntry& g, NearBoneCache* cache, std::size_t i,
                       const Box& query, std::vector<std::int32_t>* out);

// Clears *cache unless it was made for bone version `version` with `slots` entries.
void ResetNearBone(std::int64_t version, std::size_t slots, NearBoneCache* cache);

}  // namespace arthrosim::collision::internal
