#pragma once
// The render Scene: plain triangle data built from (Model, State) for one frame, so drawing
// never touches physics. BuildScene recomputes every surface (soft-body boundary of the alive
// tets, bones, thread tube, instrument shapes) and its per-vertex normals from scratch.
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "arthrosim/core/model.h"
#include "arthrosim/core/state.h"
#include "arthrosim/core/types.h"

namespace arthrosim::render {

/// Surface appearance, shaded with Blinn-Phong under the scope light plus a wet-film glint.
struct SceneMaterial {
  float base_color[3] = {0.8f, 0.8f, 0.8f};  ///< linear RGB albedo in [0, 1]
  float specular = 0.2f;                     ///< specular strength in [0, 1] (wet tissue high)
  float shininess = 30.0f;                   ///< Blinn-Phong exponent (> 0)
  float metallic = 0.0f;                     ///< 1 tints the highlight with base_color
  float wet = 0.0f;  ///< strength of the sharp glint of the saline film, [0, 1]
  /// 0 plain, 1 suture braid stripes, 2 bone grain (cancellous where burred), 3 fibrous
  /// (tendon, muscle), 4 vascular (bursa, synovium)
  std::int32_t pattern = 0;
  float fibre_dir[3] = {1.0f, 0.0f, 0.0f};  ///< pattern 3: unit fibre axis in texture space
  float fibre_period_mm = 0.6f;             ///< pattern 3: spacing of the fibre bundles, mm
  float band = 0.0f;                        ///< pattern 3: relative albedo contrast of the bundles
};

/// One vertex: world position (mm), unit normal, texture coordinate, roughness in [0, 1] (bone:
/// how deeply the surface was burred there; soft tissue: 1 where cauterised; 0 elsewhere), and
/// the texture-space position (mm): the rest position of soft tissue and the initial position of
/// bone, so patterns stay on the tissue as it moves; the world position elsewhere.
struct Vertex {
  float pos[3];
  float normal[3];
  float uv[2];
  float rough;
  float tex[3];
};

/// What a mesh is, for view filtering and tests.
enum class MeshLayer : std::uint8_t { kSoftTissue, kBone, kThread, kInstrument, kScope };

/// One drawable triangle mesh with a single material.
struct SceneMesh {
  std::string name;  ///< body, thread, instrument or "scope"
  MeshLayer layer = MeshLayer::kSoftTissue;
  SceneMaterial material;
  std::vector<Vertex> vertices;
  std::vector<std::uint32_t> indices;  ///< 3 per triangle, counter-clockwise seen from outside
  bool visible_in_scope = true;        ///< false for the scope itself
  /// Closed surface, every edge shared by exactly two triangles with opposite windings, and
  /// positive enclosed volume (so counter-clockwise faces point outward): the renderer may then
  /// skip back faces when the eye is outside the mesh's box.
  bool closed = false;
  /// For an open part of a closed surface (a bone's cartilage, labrum, or the rest of it): that
  /// closed surface. The part's back faces are hidden exactly when the whole's are, so the
  /// renderer decides its culling on the whole. Null for every other mesh.
  std::shared_ptr<const SceneMesh> whole;
};

/// The arthroscope for the scope view: tip pose plus optics.
struct SceneScope {
  Pose pose;                  ///< tip pose; +z forward along the shaft, +y image up at zero rolls
  double lens_angle_rad = 0;  ///< direction of view from the shaft axis, tilted toward +y
  double lens_roll_rad = 0;   ///< light-post rotation of the view direction about +z
  double head_roll_rad = 0;   ///< camera-head rotation of the image up vector about +z
  double fov_rad = 0;         ///< full angle of the circular image
  double near_mm = 1, far_mm = 100;
  double diameter_mm = 4;
};

/// Camera frame of the scope view in world coordinates.
struct ViewFrame {
  Vec3 eye = Vec3::Zero();       ///< mm
  Vec3 forward = Vec3::UnitZ();  ///< unit view direction
  Vec3 up = Vec3::UnitY();       ///< unit image up, orthogonal to forward
};

/// Per tool slot line of the overlay.
struct ToolOverlay {
  int slot = 0;
  std::string instrument;  ///< instrument name
  std::string kind;        ///< InstrumentKindName
  double force_n = 0;      ///< |contact force|, N
  double jaw = 0;          ///< 0 open ... 1 closed
};

/// Text and bars drawn over the image. plan_step and verdict are filled by the caller
/// (scoring) and drawn when non-empty.
struct Overlay {
  bool enabled = true;
  double time_s = 0;
  std::vector<ToolOverlay> tools;  ///< inserted instruments only, slot order
  std::string plan_step;
  std::string verdict;
};

struct Scene {
  std::vector<SceneMesh> meshes;
  SceneScope scope;
  Vec3 bounds_min = Vec3::Zero();  ///< box framed by the overview camera: bones, else all meshes
  Vec3 bounds_max = Vec3::Zero();
  Overlay overlay;
};

/// Builds the drawable scene of one frame. Reads only Model and State.
/// @throws std::invalid_argument if State arrays do not match the Model (body counts).
Scene BuildScene(const Model& model, const State& state);

/// Material for a soft body or bone by its name ("cartilage", "muscle"/"belly", "bursa",
/// "synov", "biceps", "labrum", "ligament" substrings): cartilage smooth bluish-white, bone
/// ivory, muscle red with striation, bursa and synovium reddish with vessels, tendon, biceps and
/// ligament white, glossy and fibrous; soft bodies without a hint are tendon. Fibrous materials
/// get fibre_dir = +x (BuildScene sets each body's own axis).
SceneMaterial TissueMaterial(const std::string& body_name, bool is_bone);

/// Name of the SceneMesh of a bone's own tissue (BoneModel::tissues): "humerus/cartilage". A bone
/// with tissues becomes one mesh of the bone itself (named as the bone) followed by one mesh per
/// tissue, in BoneModel::tissues order, each with its own material and tissue id.
std::string BoneTissueMeshName(const std::string& bone, const std::string& tissue);

/// World camera frame of the scope: view direction = +z tilted lens_angle toward +y, rotated by
/// lens_roll about +z; image up = +y rotated by head_roll about +z, made orthogonal to forward.
ViewFrame ScopeViewFrame(const SceneScope& scope);

/// Scope tip pose at `eye` (mm) whose oblique view (lens tilted `lens_angle_rad` toward +y, zero
/// rolls) looks at `target` with the image up as close as possible to `up_hint`: the pose form of
/// arthrosim::AimScopeView (core/scope_aim.h), which scripts and scenarios aim with too.
Pose AimScope(const Vec3& eye, const Vec3& target, const Vec3& up_hint, double lens_angle_rad);

}  // namespace arthrosim::render
