#pragma once
// Cutting (Choi et al. 2020, section III.1 and Fig. 2): the scissors cut muscle and tendon, the
// cutter cuts suture. Both act only on steps where the jaw closes, with the triangle spanned by
// the blade vertices: the hinge and the two blade tips of the one instrument geometry
// (collision/instrument_shape.h), i.e. the region between the blades that the closing sweeps.
// docs/operations.md gives the choices and thresholds (scenario `operations.scissors`,
// `operations.cutter`).
#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "arthrosim/collision/tet_query.h"
#include "arthrosim/instruments/instruments.h"

namespace arthrosim::instruments {

/// The cutting triangle of a bladed instrument (scissors, cutter) in this tool state: hinge, tip
/// of blade 0, tip of blade 1, world mm. False (tri untouched) if the slot holds no bladed tool.
bool BladeTriangle(const Model& model, const ToolState& tool, std::array<Vec3, 3>* tri);

/// True if the jaw closed by more than min_step (0 open ... 1 closed) since `prev` with the same
/// instrument in the slot (a tool exchange is never a closing).
bool JawClosing(const ToolState& now, const ToolState& prev, double min_step);

/// The alive tets of soft body `body` that triangle `tri` intersects at the state's current
/// positions, ascending, through the element tree *tree (built or refit here as needed).
void TetsCrossedByTriangle(const State& state, int body, const std::array<Vec3, 3>& tri,
                           collision::TetTree* tree, std::vector<std::int32_t>* out);

/// Rest volume (mm^3) of tet `t` of a body: |det| / 6 of its rest positions.
double TetRestVolume(const SoftBodyState& body, std::int32_t t);

/// The scissors operation: while the jaw closes and the blades touch a soft body (a contact of
/// this slot on it this step), removes (mode remove) or splits along the blade plane (mode split,
/// SplitTetsByPlane) the tets the blade triangle crosses; one `cut` event per
/// body
/// ("tets=N ids=a,b,... volume_mm3=V mode=remove"), position = centroid of the cut tets.
void ScissorsCut(const Model& model, int slot, const StepContext& context, State* state,
                 InstrumentScratch* scratch);

/// Result of a split-mode cut of one body.
struct SplitResult {
  int split_tets = 0;        ///< tets replaced by their pieces
  int new_nodes = 0;         ///< nodes appended: edge points and the copies that separate
  int new_tets = 0;          ///< pieces appended
  double volume_mm3 = 0;     ///< rest volume of the split tets (their pieces hold the same)
  double min_quality = 1.0;  ///< smallest RadiusRatio of a piece at rest
};

/// Split mode: cuts the tets `tets` (alive, ascending, of soft body `body`) along the plane
/// through `point` with unit normal `normal` (world, current positions). A node of those tets
/// whose edge to the other side crosses the plane within snap_fraction (in [0, 0.5)) of the
/// edge from it counts as on the plane (the cut passes through it: no sliver); so does a node an
/// earlier split made. Each crossed tet is cut by the plane through its on-plane nodes and edge
/// points into one convex piece per side (tet, pyramid or prism), split into tets; every other
/// alive tet holding a cut edge (found through *tree) is bisected at its edge points in cut
/// order, and the quads on shared faces take the diagonal that order gives, so the mesh stays
/// conforming. Pieces are positive at rest, the rest volume is conserved up to rounding, each
/// crossed piece lies on one side. The sides come apart: a node used on both sides gets one node
/// per side (an earlier copy at the same rest position if one exists, else a new copy); for a
/// node on the plane, the unsplit tets around it that lie on one side count too (on the node's
/// other side they take its copy), so a cut continuing an earlier one parts the earlier rim. A
/// crossed tet the plane does not divide is replaced only if one of its nodes changes. New nodes
/// interpolate x, v and x_rest along their edge.
SplitResult SplitTetsByPlane(const Model& model, int body, std::span<const std::int32_t> tets,
                             const Vec3& point, const Vec3& normal, double snap_fraction,
                             collision::TetTree* tree, physics::SoftSystem* soft, State* state);

/// Normalised quality of a tet: 3 * inradius / circumradius, 1 for the regular tet, 0 flat;
/// negative for an inverted one.
double RadiusRatio(const Vec3& p0, const Vec3& p1, const Vec3& p2, const Vec3& p3);

/// The cutter operation: on the step the jaw closes past operations.cutter.cut_at_jaw (the
/// blades meet: one cut per stroke), if a thread segment lies between the blades
/// (within operations.cutter.reach_mm of the blade triangle), the segment nearest to the
/// triangle is cut: of its two nodes the one farther from the bone along the thread is the
/// Cutting_Point, and it and every node beyond it up to the free end are removed (nodes
/// connected to the bone: the thread's fixed nodes and nodes held by a constraint to a bone).
/// Constraints on removed nodes go with them. One `thread_cut` event per cut ("segment=k
/// cutting_point=n removed_nodes=m"), position = nearest point of the segment.
void ThreadCutter(const Model& model, int slot, const StepContext& context, State* state,
                  InstrumentScratch* scratch);

/// The Cutting_Point rule on one thread cut at segment (k, k+1): returns the first node to remove
/// and sets *toward_end (+1: nodes cut_point..n-1 go, -1: nodes 0..cut_point go). The bone side is
/// the side holding a bone-connected node; when both sides hold one only the Cutting_Point goes
/// (*toward_end = 0) and both strands stay attached; when neither does, the higher-index side
/// goes.
std::int32_t CuttingPoint(const Model& model, const State& state, int thread, std::int32_t segment,
                          int* toward_end);

}  // namespace arthrosim::instruments
