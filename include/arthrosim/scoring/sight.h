#pragma once
// Line of sight in a recorded frame: whether tissue or bone hides a point from the scope. The
// surfaces are those of the run file's frame (the scenario's soft bodies as the boundary of their
// alive tets at the frame's node positions, and the bones' current surfaces, burring included);
// threads and instruments hide nothing. Deterministic: the answer depends only on the frame.
#include <cstdint>
#include <vector>

#include "arthrosim/core/model.h"
#include "arthrosim/core/state.h"

namespace arthrosim::scoring {

/// The tissue and bone surfaces of one frame, their triangles in chunks of consecutive ones with
/// a box each (surface triangles come in spatially coherent order), for segment queries.
class SightBlockers {
 public:
  /// Takes the surfaces of `state` (its arrays in Model order). A soft body's boundary is
  /// extracted again when its tets or their alive flags change (else only its node positions and
  /// boxes are refreshed); a bone's surface is taken again when its revision or size changes
  /// (State::bones[i].revision contract).
  /// @throws std::invalid_argument if the state's body counts differ from the model's or a
  /// triangle or tet names a node the body lacks.
  void Update(const Model& model, const State& state);

  /// Whether the segment from `from` to `to` (mm) crosses a surface triangle, ignoring the
  /// crossings closer than `skip_from_mm` to `from` or `skip_to_mm` to `to` (measured along the
  /// segment). False when the skipped parts cover the whole segment.
  bool Blocked(const Vec3& from, const Vec3& to, double skip_from_mm, double skip_to_mm) const;

 private:
  /// An axis-aligned box, mm.
  struct Box {
    Vec3 lo, hi;
  };
  struct Body {
    std::vector<mesh::Tet> tets;  // soft: the topology the triangles were taken from
    std::vector<std::uint8_t> alive;
    std::uint64_t revision = 0;  // bone: the surface the triangles were taken from
    std::size_t nodes = 0, tris = 0;
    bool built = false;
    std::vector<Vec3> vertices;        // the body's nodes this frame, mm
    std::vector<mesh::Tri> triangles;  // surface triangles, node indices
    std::vector<Box> chunk_boxes;      // box of triangles [kChunk c, kChunk (c + 1))
  };
  /// Refreshes a body's chunk boxes from its vertices.
  static void FitChunks(Body* b);
  std::vector<Body> soft_, bones_;
};

/// Whether the scope sees the point `tip_mm` in this frame: inside its view cone (PointInView)
/// and no tissue or bone between the scope's eye and the point. Crossings within the camera's
/// near distance of the eye (clipped by the renderer too) and within `tip_margin_mm` of the point
/// (tissue the tip touches or has barely entered: its head still shows) do not hide it.
/// `blockers` must hold the same frame's surfaces.
bool TipVisible(const Model& model, const CameraState& camera, const Vec3& tip_mm,
                double tip_margin_mm, const SightBlockers& blockers);

/// How far inside or behind its surface a landmark may lie and still count as seen, mm: landmarks
/// on tissue sit up to half a tendon's thickness (2.5 mm) inside it, so the surface over them
/// must not hide them.
inline constexpr double kLandmarkSightMarginMm = 3.0;

/// One frame's sight queries. The frame's surfaces are taken into `blockers` at the first query
/// whose point is inside the view cone (most frames need none) and reused by the later ones.
/// `model`, `state` and `blockers` must outlive it.
class FrameSight {
 public:
  FrameSight(const Model& model, const State& state, SightBlockers* blockers)
      : model_(&model), state_(&state), blockers_(blockers) {}
  /// TipVisible for `point_mm` in this frame, crossings within `margin_mm` of the point ignored.
  bool Sees(const Vec3& point_mm, double margin_mm);
  /// Whether landmark `index` (Model::landmarks) is seen: Sees(its position,
  /// kLandmarkSightMarginMm); false for an index out of range.
  bool SeesLandmark(int index);

 private:
  const Model* model_;
  const State* state_;
  SightBlockers* blockers_;
  bool updated_ = false;
};

}  // namespace arthrosim::scoring
