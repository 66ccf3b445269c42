#include "arthrosim/render/scene.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <memory>
#include <numbers>
#include <stdexcept>

#include "arthrosim/core/scope_aim.h"
#include "arthrosim/mesh/surface.h"
#include "arthrosim/mesh/surface_tissue.h"
#include "instrument_shapes.h"
#include "mesh_builder.h"
#include "surface_cache.h"

namespace arthrosim::render {
namespace {

// Depth (mm) of bone removal at which a burred vertex is fully rough.
constexpr double kFullRoughDepthMm = 0.5;
constexpr int kThreadSides = 8;

SceneMaterial Make(float r, float g, float b, float specular, float shininess, float metallic,
                   int pattern, float wet = 0.0f) {
  SceneMaterial m;
  m.base_color[0] = r;
  m.base_color[1] = g;
  m.base_color[2] = b;
  m.specular = specular;
  m.shininess = shininess;
  m.metallic = metallic;
  m.pattern = pattern;
  m.wet = wet;
  return m;
}

SceneMaterial Fibrous(SceneMaterial m, float period_mm, float band) {
  m.fibre_period_mm = period_mm;
  m.band = band;
  return m;
}

bool Contains(const std::string& s, const char* what) { return s.find(what) != std::string::npos; }

std::string Lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

Vertex MakeVertex(const Vec3& p) {
  Vertex v{};
  for (int k = 0; k < 3; ++k) v.pos[k] = v.tex[k] = static_cast<float>(p[k]);
  return v;
}

void SetTex(const Vec3& p, Vertex* v) {
  for (int k = 0; k < 3; ++k) v->tex[k] = static_cast<float>(p[k]);
}

// Fibre axis of a body: the principal axis (largest spread) of its rest nodes; the rotator-cuff
// muscles and tendons run along their length.
void SetFibreAxis(const Points& rest, SceneMaterial* m) {
  if (rest.cols() < 2) return;
  const Vec3 mean = rest.rowwise().mean();
  Mat3 cov = Mat3::Zero();
  for (Eigen::Index i = 0; i < rest.cols(); ++i) {
    const Vec3 d = rest.col(i) - mean;
    cov += d * d.transpose();
  }
  const Eigen::SelfAdjointEigenSolver<Mat3> eig(cov);
  Vec3 axis = eig.eigenvectors().col(2);
  // a fixed sign, so the pattern does not depend on the solver's choice
  const Eigen::Index big = [&] {
    Eigen::Index k = 0;
    axis.cwiseAbs().maxCoeff(&k);
    return k;
  }();
  if (axis[big] < 0) axis = -axis;
  for (int k = 0; k < 3; ++k) m->fibre_dir[k] = static_cast<float>(axis[k]);
}

// Indexed triangles over a subset of `x`'s columns: only referenced nodes become vertices.
SceneMesh TriangleMesh(const Points& x, const std::vector<mesh::Tri>& tris,
                       const std::string& what) {
  SceneMesh mesh;
  std::vector<std::int32_t> remap(x.cols(), -1);
  mesh.indices.reserve(3 * tris.size());
  for (const mesh::Tri& t : tris) {
    for (std::int32_t n : t) {
      if (n < 0 || n >= x.cols()) {
        throw std::invalid_argument(what + ": triangle references node " + std::to_string(n) +
                                    " of " + std::to_string(x.cols()));
      }
      if (remap[n] < 0) {
        remap[n] = static_cast<std::int32_t>(mesh.vertices.size());
        mesh.vertices.push_back(MakeVertex(x.col(n)));
      }
      mesh.indices.push_back(static_cast<std::uint32_t>(remap[n]));
    }
  }
  return mesh;
}

void AppendSoftBodies(const Model& model, const State& state, Scene* scene) {
  for (std::size_t i = 0; i < model.soft_bodies.size(); ++i) {
    const SoftBodyState& s = state.soft_bodies[i];
    if (!s.tet_alive.empty() && s.tet_alive.size() != s.tets.size()) {
      throw std::invalid_argument("soft body '" + model.soft_bodies[i].name +
                                  "': tet_alive size differs from tets");
    }
    // the current boundary of the alive tets, so cut and shaved faces are surface too; the
    // topology is memoised (it changes only when tets are cut), positions come from this frame
    const std::shared_ptr<const SoftTopology> topo = CachedSoftTopology(s.tets, s.tet_alive);
    if (topo->min_node < 0 || topo->max_node >= s.x.cols()) {
      const std::int32_t bad = topo->min_node < 0 ? topo->min_node : topo->max_node;
      throw std::invalid_argument("soft body '" + model.soft_bodies[i].name +
                                  "': triangle references node " + std::to_string(bad) + " of " +
                                  std::to_string(s.x.cols()));
    }
    SceneMesh mesh;
    mesh.vertices.resize(topo->nodes.size());
    for (std::size_t v = 0; v < topo->nodes.size(); ++v) {
      mesh.vertices[v] = MakeVertex(s.x.col(topo->nodes[v]));
      if (topo->nodes[v] < s.x_rest.cols()) SetTex(s.x_rest.col(topo->nodes[v]), &mesh.vertices[v]);
      // electrocautery marks (docs/operations.md): charred, coagulated tissue (mesh shader)
      const auto node = static_cast<std::size_t>(topo->nodes[v]);
      if (node < s.cauterized.size() && s.cauterized[node] != 0) mesh.vertices[v].rough = 1.0f;
    }
    mesh.indices = topo->indices;
    mesh.name = model.soft_bodies[i].name;
    mesh.layer = MeshLayer::kSoftTissue;
    mesh.material = TissueMaterial(mesh.name, false);
    if (mesh.material.pattern == 3)
      SetFibreAxis(model.soft_bodies[i].rest_mesh.nodes, &mesh.material);
    ComputeVertexNormals(&mesh);
    // inverted tets on the boundary can fold the surface; the volume sign catches a body turned
    // inside out, not a local fold (see Renderer back-face culling)
    mesh.closed = topo->closed && SignedVolume(mesh) > 0;
    scene->meshes.push_back(std::move(mesh));
  }
}

// Vertices (normals, grain in uv.x, burr roughness) and triangles of a bone surface.
SceneMesh BoneGeometry(const mesh::TriMesh& now, const mesh::TriMesh& initial,
                       const std::string& what) {
  SceneMesh mesh = TriangleMesh(now.nodes, now.tris, what);
  ComputeVertexNormals(&mesh);
  mesh.closed = IsClosedSurface(mesh.indices) && SignedVolume(mesh) > 0;
  // subtle grain of the bone surface: a smooth, deterministic function of position
  for (Vertex& v : mesh.vertices) {
    const double g =
        std::sin(1.3 * v.pos[0] + 0.7 * v.pos[2]) * std::sin(1.1 * v.pos[1] - 0.9 * v.pos[0]) +
        0.5 * std::sin(2.9 * v.pos[2] + 2.3 * v.pos[1]);
    v.uv[0] = static_cast<float>(0.95 + 0.035 * g);
  }
  // burred areas: how far a vertex moved from its initial place (same topology only)
  if (now.nodes.cols() == initial.nodes.cols()) {
    std::vector<std::int32_t> remap(now.nodes.cols(), -1);
    std::int32_t next = 0;
    for (const mesh::Tri& t : now.tris) {
      for (std::int32_t n : t) {
        if (remap[n] < 0) remap[n] = next++;
      }
    }
    for (Eigen::Index n = 0; n < now.nodes.cols(); ++n) {
      if (remap[n] < 0) continue;
      const double depth = (now.nodes.col(n) - initial.nodes.col(n)).norm();
      mesh.vertices[remap[n]].rough = static_cast<float>(std::min(1.0, depth / kFullRoughDepthMm));
      SetTex(initial.nodes.col(n), &mesh.vertices[remap[n]]);
    }
  }
  return mesh;
}

// The triangles of `whole` (one per triangle of the bone surface, in order) labelled `label`,
// over the vertices they use.
SceneMesh TissuePart(const SceneMesh& whole, const std::vector<std::int8_t>& labels,
                     std::int8_t label) {
  SceneMesh part;
  std::vector<std::int32_t> remap(whole.vertices.size(), -1);
  for (std::size_t t = 0; t < labels.size() && 3 * t + 2 < whole.indices.size(); ++t) {
    if (labels[t] != label) continue;
    for (std::size_t k = 3 * t; k < 3 * t + 3; ++k) {
      const std::uint32_t v = whole.indices[k];
      if (remap[v] < 0) {
        remap[v] = static_cast<std::int32_t>(part.vertices.size());
        part.vertices.push_back(whole.vertices[v]);
      }
      part.indices.push_back(static_cast<std::uint32_t>(remap[v]));
    }
  }
  return part;
}

void AppendBones(const Model& model, const State& state, Scene* scene) {
  for (std::size_t i = 0; i < model.bones.size(); ++i) {
    const BoneModel& bone = model.bones[i];
    const mesh::TriMesh& now = state.bones[i].surface;
    const mesh::TriMesh& initial = bone.surface;
    // geometry memoised: a bone changes only when burred or drilled
    const std::shared_ptr<const SceneMesh> whole = CachedBoneMesh(
        now, initial.nodes, [&] { return BoneGeometry(now, initial, "bone '" + bone.name + "'"); });
    SceneMesh mesh = *whole;
    mesh.name = bone.name;
    mesh.layer = MeshLayer::kBone;
    mesh.material = TissueMaterial(mesh.name, true);
    if (bone.tissues.empty()) {
      scene->meshes.push_back(std::move(mesh));
      continue;
    }
    // Tissues of their own (cartilage, labrum): one mesh each after the bone's, so each has its
    // material and its id; the parts are open surfaces, culled as the whole bone is.
    const std::vector<std::int8_t> labels = mesh::TriangleTissues(initial, bone.tri_tissue, now);
    for (std::int8_t label = mesh::kBoneTissue; label < static_cast<int>(bone.tissues.size());
         ++label) {
      SceneMesh part = TissuePart(mesh, labels, label);
      part.layer = MeshLayer::kBone;
      part.whole = whole;
      if (label == mesh::kBoneTissue) {
        part.name = bone.name;
        part.material = mesh.material;
      } else {
        const std::string& tissue = bone.tissues[static_cast<std::size_t>(label)];
        part.name = BoneTissueMeshName(bone.name, tissue);
        part.material = TissueMaterial(tissue, false);
      }
      scene->meshes.push_back(std::move(part));
    }
  }
}

void AppendThreads(const Model& model, const State& state, Scene* scene) {
  for (std::size_t i = 0; i < model.threads.size(); ++i) {
    const ThreadState& t = state.threads[i];
    SceneMesh mesh;
    mesh.name = model.threads[i].name;
    mesh.layer = MeshLayer::kThread;
    // No. 2 FiberWire: blue braid with white tracer
    mesh.material = Make(0.10f, 0.22f, 0.75f, 0.35f, 40.0f, 0.0f, 1);
    MeshBuilder b(&mesh, Eigen::Isometry3d::Identity());
    const double radius = 0.5 * model.threads[i].diameter_mm;
    // one tube per run of consecutive alive nodes
    std::vector<Vec3> run;
    auto flush = [&] {
      if (run.size() >= 2) b.Tube(run, radius, kThreadSides);
      run.clear();
    };
    for (Eigen::Index n = 0; n < t.x.cols(); ++n) {
      const bool alive = t.node_alive.empty() || t.node_alive[n];
      if (alive) {
        run.push_back(t.x.col(n));
      } else {
        flush();
      }
    }
    flush();
    scene->meshes.push_back(std::move(mesh));
  }
}

void AppendTools(const Model& model, const State& state, Scene* scene) {
  for (int slot = 0; slot < kToolSlots; ++slot) {
    const ToolState& tool = state.tools[slot];
    if (tool.instrument < 0) continue;
    if (tool.instrument >= static_cast<int>(model.instruments.size())) {
      throw std::invalid_argument("tool slot " + std::to_string(slot) + ": instrument index " +
                                  std::to_string(tool.instrument) + " out of range");
    }
    const InstrumentModel& im = model.instruments[tool.instrument];
    SceneMesh metal, dark;
    metal.name = dark.name = im.name;
    metal.layer = dark.layer = MeshLayer::kInstrument;
    metal.material = Make(0.70f, 0.72f, 0.75f, 0.9f, 60.0f, 1.0f, 0);
    dark.material = Make(0.08f, 0.08f, 0.09f, 0.4f, 30.0f, 0.0f, 0);
    AppendInstrument(im, tool.jaw, tool.pose, &metal, &dark);
    scene->meshes.push_back(std::move(metal));
    if (!dark.indices.empty()) scene->meshes.push_back(std::move(dark));

    ToolOverlay line;
    line.slot = slot;
    line.instrument = im.name;
    line.kind = InstrumentKindName(im.kind);
    line.force_n = tool.force_n.norm();
    line.jaw = tool.jaw;
    scene->overlay.tools.push_back(line);
  }
}

void ComputeBounds(Scene* scene) {
  Eigen::AlignedBox3d box;
  for (int pass = 0; pass < 2 && box.isEmpty(); ++pass) {
    for (const SceneMesh& m : scene->meshes) {
      if (pass == 0 && m.layer != MeshLayer::kBone) continue;
      if (pass == 1 && (m.layer == MeshLayer::kScope || m.layer == MeshLayer::kInstrument)) {
        continue;
      }
      for (const Vertex& v : m.vertices) box.extend(Vec3(v.pos[0], v.pos[1], v.pos[2]));
    }
  }
  if (box.isEmpty())
    box.extend(scene->scope.pose.position_mm)
        .extend(scene->scope.pose.position_mm + Vec3::Constant(10.0));
  scene->bounds_min = box.min();
  scene->bounds_max = box.max();
}

}  // namespace

SceneMaterial TissueMaterial(const std::string& body_name, bool is_bone) {
  const std::string n = Lower(body_name);
  // hyaline cartilage: smooth, bluish-white, very wet
  if (Contains(n, "cartilage")) return Make(0.80f, 0.85f, 0.93f, 0.6f, 70.0f, 0.0f, 0, 0.9f);
  // ivory cortical bone, dull; cancellous and bleeding where burred (pattern 2)
  if (is_bone) return Make(0.86f, 0.79f, 0.60f, 0.12f, 12.0f, 0.0f, 2, 0.3f);
  if (Contains(n, "muscle") || Contains(n, "belly")) {
    return Fibrous(Make(0.60f, 0.12f, 0.10f, 0.25f, 40.0f, 0.0f, 3, 0.45f), 2.5f, 0.22f);
  }
  if (Contains(n, "bursa") || Contains(n, "synov")) {
    return Make(0.80f, 0.40f, 0.36f, 0.35f, 40.0f, 0.0f, 4, 0.7f);
  }
  // fibrocartilage: white with a faint pink-grey, glossy, less smooth than hyaline cartilage
  if (Contains(n, "labrum")) return Make(0.90f, 0.86f, 0.84f, 0.5f, 60.0f, 0.0f, 0, 0.7f);
  if (Contains(n, "biceps")) {
    return Fibrous(Make(0.92f, 0.87f, 0.76f, 0.5f, 70.0f, 0.0f, 3, 0.8f), 1.5f, 0.10f);
  }
  // tendon and ligament (default for soft tissue): white, glossy, fibre bundles
  return Fibrous(Make(0.93f, 0.91f, 0.84f, 0.5f, 80.0f, 0.0f, 3, 0.8f), 1.5f, 0.10f);
}

std::string BoneTissueMeshName(const std::string& bone, const std::string& tissue) {
  return bone + "/" + tissue;
}

ViewFrame ScopeViewFrame(const SceneScope& scope) {
  const Mat3 r = scope.pose.orientation.normalized().toRotationMatrix();
  const double cl = std::cos(scope.lens_roll_rad), sl = std::sin(scope.lens_roll_rad);
  const double ch = std::cos(scope.head_roll_rad), sh = std::sin(scope.head_roll_rad);
  const double sa = std::sin(scope.lens_angle_rad), ca = std::cos(scope.lens_angle_rad);
  // forward: (0, sin a, cos a) rotated by lens_roll about +z; up: +y rotated by head_roll
  const Vec3 f_local(-sl * sa, cl * sa, ca);
  Vec3 up_local(-sh, ch, 0);
  up_local -= up_local.dot(f_local) * f_local;
  if (up_local.norm() < 1e-9) up_local = Vec3(ch, sh, 0);  // looking along the up vector
  ViewFrame v;
  v.eye = scope.pose.position_mm;
  v.forward = (r * f_local).normalized();
  v.up = (r * up_local.normalized()).normalized();
  return v;
}

Pose AimScope(const Vec3& eye, const Vec3& target, const Vec3& up_hint, double lens_angle_rad) {
  return Pose{eye, AimScopeView(eye, target, lens_angle_rad, up_hint)};
}

Scene BuildScene(const Model& model, const State& state) {
  if (state.soft_bodies.size() != model.soft_bodies.size() ||
      state.bones.size() != model.bones.size() || state.threads.size() != model.threads.size()) {
    throw std::invalid_argument("BuildScene: State body counts do not match the Model");
  }
  Scene scene;
  scene.scope.pose = state.camera.pose;
  scene.scope.lens_angle_rad = model.camera.lens_angle_deg * std::numbers::pi / 180;
  scene.scope.lens_roll_rad = state.camera.lens_roll_rad;
  scene.scope.head_roll_rad = state.camera.head_roll_rad;
  scene.scope.fov_rad = model.camera.fov_deg * std::numbers::pi / 180;
  scene.scope.near_mm = model.camera.near_mm;
  scene.scope.far_mm = model.camera.far_mm;
  scene.scope.diameter_mm = model.camera.diameter_mm;
  scene.overlay.time_s = state.time_s;

  AppendSoftBodies(model, state, &scene);
  AppendBones(model, state, &scene);
  AppendThreads(model, state, &scene);
  AppendTools(model, state, &scene);

  SceneMesh scope;
  scope.name = "scope";
  scope.layer = MeshLayer::kScope;
  scope.visible_in_scope = false;
  scope.material = Make(0.20f, 0.20f, 0.22f, 0.8f, 50.0f, 1.0f, 0);
  AppendScope(state.camera.pose, model.camera.diameter_mm, &scope);
  scene.meshes.push_back(std::move(scope));

  ComputeBounds(&scene);
  return scene;
}

}  // namespace arthrosim::render
