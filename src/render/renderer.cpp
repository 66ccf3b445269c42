#include "arthrosim/render/renderer.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <stdexcept>
#include <string>
#include <vector>

#include "arthrosim/core/enum_names.h"
#include "cull.h"
#include "gl_api.h"
#include "overlay.h"
#include "shaders.h"
#include "text.h"

namespace arthrosim::render {
namespace {

using Mat4 = Eigen::Matrix4d;

// Inside the joint with nothing near the lens: dark, reddish saline.
constexpr float kFluidColor[3] = {0.05f, 0.03f, 0.03f};
constexpr float kOverviewBackground[3] = {0.12f, 0.13f, 0.15f};
constexpr float kScopeAmbient = 0.05f;
constexpr float kOverviewAmbient = 0.18f;
// The rectilinear pass cannot reach 90 deg off axis; wider lenses are clamped.
constexpr double kMaxHalfFovRad = 80.0 * 3.14159265358979323846 / 180.0;
// Sides of the polygons that bound the image circle (lens pass) and the texels it samples.
constexpr int kFanSides = 64;
// Auto-exposure metering: the lens pass drawn at kMeterSize^2 pixels in linear radiance. The
// gain puts the mean luminance of the image circle at kKeyRadiance (tone-mapped 0.45, a mid
// grey) unless that would push the 98.5th percentile of the brightest channel beyond
// kPeakRadiance (tone-mapped 248 of 255; wet glints above it may clip), within
// [kMinExposure, kMaxExposure].
constexpr int kMeterSize = 64;
constexpr double kKeyRadiance = 0.43;
constexpr double kPeakRadiance = 2.6;
constexpr double kPeakQuantile = 0.985;
constexpr double kMinExposure = 0.03;
constexpr double kMaxExposure = 2.5;
// Fibre streaks fade out where one period of the finer ones spans fewer than 4 pixels.
constexpr double kFibreMinPixels = 4.0;
constexpr double kFibreFinePeriod = 0.43;  // finer streaks' period / fibre_period_mm
constexpr double kCrimpPeriodMm = 3.0;

Mat4 LookAt(const Vec3& eye, const Vec3& forward, const Vec3& up) {
  const Vec3 f = forward.normalized();
  const Vec3 s = f.cross(up).normalized();
  const Vec3 u = s.cross(f);
  Mat4 m = Mat4::Identity();
  m.block<1, 3>(0, 0) = s.transpose();
  m.block<1, 3>(1, 0) = u.transpose();
  m.block<1, 3>(2, 0) = -f.transpose();
  m(0, 3) = -s.dot(eye);
  m(1, 3) = -u.dot(eye);
  m(2, 3) = f.dot(eye);
  return m;
}

Mat4 Perspective(double tan_half_y, double aspect, double n, double f) {
  Mat4 m = Mat4::Zero();
  m(0, 0) = 1.0 / (tan_half_y * aspect);
  m(1, 1) = 1.0 / tan_half_y;
  m(2, 2) = -(f + n) / (f - n);
  m(2, 3) = -2.0 * f * n / (f - n);
  m(3, 2) = -1.0;
  return m;
}

// Clears colour (to `background`, or to black, "no tissue", for the tissue-id pass) and depth.
void ClearColourAndDepth(bool ids_mode, const float background[3]) {
  if (ids_mode) {
    glClearColor(0, 0, 0, 1);
  } else {
    glClearColor(background[0], background[1], background[2], 1.0f);
  }
  glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
}

// Throws RenderError("<failed>" + the info log) unless `object`'s `status` (a shader's compile
// or a program's link status, read by get_status) is set.
template <class GetStatus, class GetLog>
void CheckStatus(GetStatus get_status, GetLog get_log, GLuint object, GLenum status,
                 const char* failed) {
  GLint ok = 0;
  get_status(object, status, &ok);
  if (ok) return;
  char log[2048] = {};
  get_log(object, sizeof log, nullptr, log);
  throw RenderError(std::string(failed) + log);
}

GLuint Compile(const GlApi& gl, GLenum type, const char* source) {
  const GLuint s = gl.CreateShader(type);
  gl.ShaderSource(s, 1, &source, nullptr);
  gl.CompileShader(s);
  CheckStatus(gl.GetShaderiv, gl.GetShaderInfoLog, s, GL_COMPILE_STATUS, "GLSL compile failed: ");
  return s;
}

GLuint Link(const GlApi& gl, const char* vs, const char* fs) {
  const GLuint v = Compile(gl, GL_VERTEX_SHADER, vs), f = Compile(gl, GL_FRAGMENT_SHADER, fs);
  const GLuint p = gl.CreateProgram();
  gl.AttachShader(p, v);
  gl.AttachShader(p, f);
  gl.LinkProgram(p);
  gl.DeleteShader(v);
  gl.DeleteShader(f);
  CheckStatus(gl.GetProgramiv, gl.GetProgramInfoLog, p, GL_LINK_STATUS, "GLSL link failed: ");
  return p;
}

struct Viewport {
  int x = 0, y = 0, w = 0, h = 0;
};

// Exposure gain for the linear RGBA radiance of the metering pass (size x size, the image
// circle inscribed); see kKeyRadiance.
double MeteredExposure(const std::vector<float>& rgba, int size) {
  std::vector<float> peak;
  peak.reserve(static_cast<std::size_t>(size) * size);
  double sum = 0;
  const double c = 0.5 * size, r2 = (0.5 * size - 1) * (0.5 * size - 1);
  for (int y = 0; y < size; ++y) {
    for (int x = 0; x < size; ++x) {
      const double dx = x + 0.5 - c, dy = y + 0.5 - c;
      if (dx * dx + dy * dy > r2) continue;
      const float* p = &rgba[4 * (static_cast<std::size_t>(y) * size + x)];
      sum += 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2];
      peak.push_back(std::max({p[0], p[1], p[2]}));
    }
  }
  if (peak.empty()) return 1.0;
  const double mean = sum / static_cast<double>(peak.size());
  const auto k = static_cast<std::ptrdiff_t>(kPeakQuantile * static_cast<double>(peak.size() - 1));
  std::nth_element(peak.begin(), peak.begin() + k, peak.end());
  const double gain = std::min(kKeyRadiance / std::max(mean, 1e-6),
                               kPeakRadiance / std::max<double>(peak[k], 1e-6));
  return std::clamp(gain, kMinExposure, kMaxExposure);
}

}  // namespace

constexpr EnumName<View> kViewNames[] = {
    {View::kScope, "scope"}, {View::kOverview, "overview"}, {View::kBoth, "both"}};

View ParseView(const std::string& name) {
  if (const std::optional<View> view = ValueIn(kViewNames, name)) return *view;
  throw std::invalid_argument("view '" + name + "': expected scope, overview or both");
}

const char* ViewName(View view) { return NameIn(kViewNames, view, "?"); }

struct Renderer::Impl {
  OSMesaContext ctx = nullptr;
  std::vector<unsigned char> buffer;  // OSMesa colour buffer, RGBA, bottom-up
  int buf_w = 0, buf_h = 0;
  GlApi gl;
  // one mesh program per SceneMaterial::pattern (0 plain, 1 braid, 2 bone, 3 fibrous, 4 vascular)
  static constexpr int kPatterns = 5;
  GLuint mesh_prog[kPatterns] = {}, post_prog = 0;
  GLuint vao = 0, vbo = 0, ebo = 0, post_vao = 0;
  GLuint fbo = 0, fbo_tex = 0, fbo_depth = 0;
  int fbo_size = 0;
  GLuint meter_fbo = 0, meter_tex = 0;  // kMeterSize^2 RGBA32F, the metering pass
  std::vector<float> meter;             // its pixels
  GLuint id_prog = 0;
  GLint id_uniform = -1, id_view_proj = -1;
  bool ids_mode = false;     // drawing tissue ids instead of colours
  double last_exposure = 1;  // gain of the last scope image
  struct MeshUniforms {
    GLint view_proj, base, spec, shininess, metal, wet, eye, light, ref2, spot_dir, spot, ambient,
        exposure, along, across, band, fade;
  } mu[kPatterns]{};
  struct {
    GLint tex, center, radius, theta_max, tan_max, k, exposure, ids;
  } pu{};
  GLuint mask_prog = 0;
  struct FanUniforms {
    GLint center, scale, inner, outer, sides, depth;
  } post_fan{}, mask_fan{};

  // Sets the polygon of kPostVertex (program `prog` must be in use); centre in NDC, scale in
  // NDC per radius unit, outer = 0 for a fan.
  void SetFan(const FanUniforms& f, double cx, double cy, double sx, double sy, double inner,
              double outer, double depth) const {
    gl.Uniform2f(f.center, float(cx), float(cy));
    gl.Uniform2f(f.scale, float(sx), float(sy));
    gl.Uniform1f(f.inner, float(inner));
    gl.Uniform1f(f.outer, float(outer));
    gl.Uniform1i(f.sides, kFanSides);
    gl.Uniform1f(f.depth, float(depth));
  }
  std::unique_ptr<Font> font;
  // one draw range per scene mesh in the shared buffers
  struct Range {
    GLsizei count;
    std::size_t first;
    GLint base_vertex;
    Eigen::AlignedBox3d box;  // of the mesh's vertices (mm)
  };
  std::vector<Range> ranges;
  std::vector<std::size_t> order;  // draw order: near layers first so depth tests cull more
  std::vector<Vertex> vertices;
  std::vector<std::uint32_t> indices;

  void MakeCurrent(int w, int h) {
    if (w != buf_w || h != buf_h) {
      buffer.assign(static_cast<std::size_t>(4) * w * h, 0);
      buf_w = w;
      buf_h = h;
    }
    if (!OSMesaMakeCurrent(ctx, buffer.data(), GL_UNSIGNED_BYTE, w, h)) {
      throw RenderError("OSMesaMakeCurrent failed");
    }
  }

  void Upload(const Scene& scene) {
    vertices.clear();
    indices.clear();
    ranges.clear();
    for (const SceneMesh& m : scene.meshes) {
      Eigen::AlignedBox3d box;
      for (const Vertex& v : m.vertices) box.extend(Vec3(v.pos[0], v.pos[1], v.pos[2]));
      ranges.push_back({static_cast<GLsizei>(m.indices.size()), indices.size(),
                        static_cast<GLint>(vertices.size()), box});
      vertices.insert(vertices.end(), m.vertices.begin(), m.vertices.end());
      indices.insert(indices.end(), m.indices.begin(), m.indices.end());
    }
    auto rank = [](MeshLayer l) {
      switch (l) {
        case MeshLayer::kInstrument:
          return 0;
        case MeshLayer::kThread:
          return 1;
        case MeshLayer::kSoftTissue:
          return 2;
        case MeshLayer::kBone:
          return 3;
        case MeshLayer::kScope:
          return 4;
      }
      return 5;
    };
    order.resize(scene.meshes.size());
    for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
    std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
      return rank(scene.meshes[a].layer) < rank(scene.meshes[b].layer);
    });
    gl.BindVertexArray(vao);
    gl.BindBuffer(GL_ARRAY_BUFFER, vbo);
    gl.BufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(vertices.size() * sizeof(Vertex)),
                  vertices.data(), GL_STREAM_DRAW);
    gl.BindBuffer(GL_ELEMENT_ARRAY_BUFFER, ebo);
    gl.BufferData(GL_ELEMENT_ARRAY_BUFFER,
                  static_cast<GLsizeiptr>(indices.size() * sizeof(std::uint32_t)), indices.data(),
                  GL_STREAM_DRAW);
  }

  void EnsureFbo(int size) {
    if (size == fbo_size) return;
    if (fbo == 0) {
      gl.GenFramebuffers(1, &fbo);
      glGenTextures(1, &fbo_tex);
      gl.GenRenderbuffers(1, &fbo_depth);
    }
    glBindTexture(GL_TEXTURE_2D, fbo_tex);
    // linear radiance beyond 1 (the lens pass exposes it); ids are exact in half floats
    glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA16F, size, size, 0, GL_RGBA, GL_FLOAT, nullptr);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
    gl.BindRenderbuffer(GL_RENDERBUFFER, fbo_depth);
    gl.RenderbufferStorage(GL_RENDERBUFFER, GL_DEPTH_COMPONENT24, size, size);
    gl.BindFramebuffer(GL_FRAMEBUFFER, fbo);
    gl.FramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, fbo_tex, 0);
    gl.FramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, fbo_depth);
    if (gl.CheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE) {
      throw RenderError("scope framebuffer incomplete");
    }
    gl.BindFramebuffer(GL_FRAMEBUFFER, 0);
    fbo_size = size;
  }

  void EnsureMeterFbo() {
    if (meter_fbo != 0) return;
    gl.GenFramebuffers(1, &meter_fbo);
    glGenTextures(1, &meter_tex);
    glBindTexture(GL_TEXTURE_2D, meter_tex);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA32F, kMeterSize, kMeterSize, 0, GL_RGBA, GL_FLOAT,
                 nullptr);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    gl.BindFramebuffer(GL_FRAMEBUFFER, meter_fbo);
    gl.FramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, meter_tex, 0);
    if (gl.CheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE) {
      throw RenderError("exposure metering framebuffer incomplete");
    }
    gl.BindFramebuffer(GL_FRAMEBUFFER, 0);
    meter.assign(static_cast<std::size_t>(4) * kMeterSize * kMeterSize, 0.0f);
  }

  // Per-material uniforms of the mesh programs: colours, lobes and the fibre pattern, whose
  // bundles fade out when a period spans fewer than kFibreMinPixels at `px_rad` radians/pixel.
  void SetMaterial(const MeshUniforms& u, const SceneMaterial& mat, double px_rad) const {
    gl.Uniform3f(u.base, mat.base_color[0], mat.base_color[1], mat.base_color[2]);
    gl.Uniform1f(u.spec, mat.specular);
    gl.Uniform1f(u.shininess, mat.shininess);
    gl.Uniform1f(u.metal, mat.metallic);
    gl.Uniform1f(u.wet, mat.wet);
    if (mat.pattern != 3) return;
    const Vec3 f = Vec3(mat.fibre_dir[0], mat.fibre_dir[1], mat.fibre_dir[2]).normalized();
    const double period = std::max<double>(mat.fibre_period_mm, 1e-3);
    const double w = 2 * 3.14159265358979323846;
    const Vec3 along = f * (w / kCrimpPeriodMm);
    gl.Uniform3f(u.along, float(along.x()), float(along.y()), float(along.z()));
    gl.Uniform1f(u.across, float(w / period));
    gl.Uniform1f(u.band, mat.band);
    // fade = clamp(2 - distance * u_fade): 1 up to kFibreMinPixels per fine period, 0 at half
    gl.Uniform1f(u.fade, float(kFibreMinPixels * px_rad / (kFibreFinePeriod * period)));
  }

  // Draws the meshes (scope view: those visible in the scope) with one camera and light.
  // `near_reach` (mm) bounds the distance from the eye to any point of the near clip rectangle;
  // `px_rad` is the angle of one pixel at the image centre; `exposure` > 0 tone-maps in the
  // shader, 0 writes linear radiance. In ids mode every mesh is drawn flat in its id colour.
  void DrawMeshes(const Scene& scene, const Mat4& view_proj, const Vec3& eye, bool scope_light,
                  const Vec3& spot_dir, double ref_mm, double near_reach, double px_rad,
                  double exposure) {
    const Eigen::Matrix4f vp = view_proj.cast<float>();
    if (ids_mode) {
      gl.UseProgram(id_prog);
      gl.UniformMatrix4fv(id_view_proj, 1, GL_FALSE, vp.data());
    } else {
      for (int p = 0; p < kPatterns; ++p) {
        const MeshUniforms& u = mu[p];
        gl.UseProgram(mesh_prog[p]);
        gl.UniformMatrix4fv(u.view_proj, 1, GL_FALSE, vp.data());
        gl.Uniform3f(u.eye, float(eye.x()), float(eye.y()), float(eye.z()));
        gl.Uniform3f(u.light, float(eye.x()), float(eye.y()), float(eye.z()));
        gl.Uniform1f(u.ref2, scope_light ? float(ref_mm * ref_mm) : 0.0f);
        gl.Uniform3f(u.spot_dir, float(spot_dir.x()), float(spot_dir.y()), float(spot_dir.z()));
        gl.Uniform1i(u.spot, scope_light ? 1 : 0);
        gl.Uniform1f(u.ambient, scope_light ? kScopeAmbient : kOverviewAmbient);
        gl.Uniform1f(u.exposure, float(exposure));
      }
    }
    int current = ids_mode ? -1 : kPatterns - 1;  // bound last above
    bool culling = false;                         // Render() starts with culling off
    gl.BindVertexArray(vao);
    for (const std::size_t i : order) {
      const SceneMesh& m = scene.meshes[i];
      if (ranges[i].count == 0 || (scope_light && !m.visible_in_scope)) continue;
      const SceneMaterial& mat = m.material;
      const int p = mat.pattern >= 1 && mat.pattern < kPatterns ? mat.pattern : 0;
      if (!ids_mode && p != current) {
        gl.UseProgram(mesh_prog[p]);
        current = p;
      }
      // Skipping hidden back faces halves the rasterised area of bones and soft tissue; the
      // box test skips the exact check for meshes far from the eye.
      const double reach = 1.01 * near_reach + 1e-3;
      // (a bone's tissue part is culled as its closed whole is)
      const bool cull = m.whole ? CullBackFaces(*m.whole, MeshBox(*m.whole), eye, reach)
                                : CullBackFaces(m, ranges[i].box, eye, reach);
      if (cull != culling) {
        if (cull) {
          glEnable(GL_CULL_FACE);
        } else {
          glDisable(GL_CULL_FACE);
        }
        culling = cull;
      }
      if (ids_mode) {
        const auto id = static_cast<unsigned>(i + 1);
        gl.Uniform3f(id_uniform, float(id & 255u) / 255.0f, float((id >> 8) & 255u) / 255.0f, 0.0f);
      } else {
        SetMaterial(mu[p], mat, px_rad);
      }
      gl.DrawElementsBaseVertex(
          GL_TRIANGLES, ranges[i].count, GL_UNSIGNED_INT,
          reinterpret_cast<const void*>(ranges[i].first * sizeof(std::uint32_t)),
          ranges[i].base_vertex);
    }
    glDisable(GL_CULL_FACE);
  }

  void RenderScope(const Scene& scene, const ViewSpec& spec, const Viewport& vp) {
    const double half = std::min(0.5 * scene.scope.fov_rad, kMaxHalfFovRad);
    const double tan_max = std::tan(half);
    const int diameter =
        std::max(2, static_cast<int>(std::lround(spec.field_stop * std::min(vp.w, vp.h))));
    // texture resolution matching the output at the image centre, where the fisheye
    // magnifies most relative to the rectilinear render
    const double centre_gain = 1.0 + spec.scope_detail * spec.distortion * (tan_max / half - 1.0);
    const int tex = std::max(2, static_cast<int>(std::ceil(diameter * centre_gain)));
    EnsureFbo(tex);

    // pass 1: rectilinear render into the square texture
    const ViewFrame f = ScopeViewFrame(scene.scope);
    const Mat4 view_proj = Perspective(tan_max, 1.0, scene.scope.near_mm, scene.scope.far_mm) *
                           LookAt(f.eye, f.forward, f.up);
    gl.BindFramebuffer(GL_FRAMEBUFFER, fbo);
    glViewport(0, 0, tex, tex);
    glDisable(GL_SCISSOR_TEST);
    ClearColourAndDepth(ids_mode, kFluidColor);
    glEnable(GL_DEPTH_TEST);
    // The lens pass samples only the inscribed disc of the texture (bilinear: one texel
    // beyond). Depth 0 outside a polygon around it (2 texels of margin) makes every mesh
    // fragment there fail the depth test before shading; the texels read are unchanged.
    gl.UseProgram(mask_prog);
    glColorMask(GL_FALSE, GL_FALSE, GL_FALSE, GL_FALSE);
    glDepthFunc(GL_ALWAYS);
    SetFan(mask_fan, 0, 0, 2.0 / tex, 2.0 / tex,
           (0.5 * tex + 2.0) / std::cos(3.14159265358979323846 / kFanSides), tex, -1.0);
    gl.BindVertexArray(post_vao);
    glDrawArrays(GL_TRIANGLE_STRIP, 0, 2 * kFanSides + 2);
    glColorMask(GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
    glDepthFunc(GL_LESS);
    const double near = scene.scope.near_mm;
    DrawMeshes(scene, view_proj, f.eye, true, f.forward, spec.light_ref_mm,
               near * std::sqrt(1.0 + 2.0 * tan_max * tan_max), 2.0 * tan_max / tex, 0.0);

    // pass 2: lens distortion and field stop into the output viewport
    glDisable(GL_DEPTH_TEST);
    if (!ids_mode && spec.auto_exposure) EnsureMeterFbo();  // binds its own texture
    gl.UseProgram(post_prog);
    gl.ActiveTexture(GL_TEXTURE0);
    glBindTexture(GL_TEXTURE_2D, fbo_tex);
    gl.Uniform1i(pu.tex, 0);
    gl.Uniform1f(pu.theta_max, float(half));
    gl.Uniform1f(pu.tan_max, float(tan_max));
    gl.Uniform1f(pu.k, float(spec.distortion));
    gl.Uniform1i(pu.ids, ids_mode ? 1 : 0);
    gl.BindVertexArray(post_vao);
    double exposure = spec.exposure;
    if (!ids_mode && spec.auto_exposure) exposure = Meter();
    last_exposure = exposure;
    gl.BindFramebuffer(GL_FRAMEBUFFER, 0);
    glViewport(vp.x, vp.y, vp.w, vp.h);
    gl.Uniform2f(pu.center, float(vp.x + 0.5 * vp.w), float(vp.y + 0.5 * vp.h));
    gl.Uniform1f(pu.radius, float(0.5 * diameter));
    gl.Uniform1f(pu.exposure, float(exposure));
    // only a polygon around the image circle (1.5 px beyond its anti-aliased rim): the rest is
    // already black
    const double px = 0.5 * diameter + 1.5;
    SetFan(post_fan, 0, 0, 2.0 / vp.w, 2.0 / vp.h,
           px / std::cos(3.14159265358979323846 / kFanSides), 0, 0);
    glDrawArrays(GL_TRIANGLE_FAN, 0, kFanSides + 2);
  }

  // The lens pass (program and texture bound, EnsureMeterFbo done) drawn small in linear radiance
  // and read back: the auto-exposure gain of this frame, a function of its content only.
  double Meter() {
    gl.BindFramebuffer(GL_FRAMEBUFFER, meter_fbo);
    glViewport(0, 0, kMeterSize, kMeterSize);
    gl.Uniform2f(pu.center, 0.5f * kMeterSize, 0.5f * kMeterSize);
    gl.Uniform1f(pu.radius, 0.5f * kMeterSize);
    gl.Uniform1f(pu.exposure, 0.0f);
    SetFan(post_fan, 0, 0, 2.0 / kMeterSize, 2.0 / kMeterSize,
           (0.5 * kMeterSize + 1.5) / std::cos(3.14159265358979323846 / kFanSides), 0, 0);
    glDrawArrays(GL_TRIANGLE_FAN, 0, kFanSides + 2);
    glPixelStorei(GL_PACK_ALIGNMENT, 4);
    glReadPixels(0, 0, kMeterSize, kMeterSize, GL_RGBA, GL_FLOAT, meter.data());
    glPixelStorei(GL_PACK_ALIGNMENT, 1);
    return MeteredExposure(meter, kMeterSize);
  }

  void RenderOverview(const Scene& scene, const ViewSpec& spec, const Viewport& vp) {
    const Vec3 centre = 0.5 * (scene.bounds_min + scene.bounds_max);
    const double radius = std::max(1.0, 0.5 * (scene.bounds_max - scene.bounds_min).norm());
    // look across the scope shaft (so the scope and instruments are seen from the side, not
    // along their axes), from the scope's side of the joint and slightly from above (+z up)
    const Vec3 shaft = scene.scope.pose.orientation.normalized() * Vec3::UnitZ();
    Vec3 dir = shaft.cross(Vec3::UnitZ());
    dir = dir.norm() > 1e-3 ? Vec3(dir.normalized()) : Vec3(1, 0, 0);
    if (dir.dot(scene.scope.pose.position_mm - centre) < 0) dir = -dir;
    dir = (dir + Vec3(0, 0, 0.6)).normalized();
    const Vec3 up = std::abs(dir.z()) > 0.99 ? Vec3::UnitY() : Vec3::UnitZ();
    const double aspect = double(vp.w) / vp.h;
    const double tan_y = std::tan(0.5 * spec.overview_fov_deg * 3.14159265358979323846 / 180);
    const double tan_min = std::min(tan_y, tan_y * aspect);
    const double dist = 1.1 * radius / std::sin(std::atan(tan_min));
    const Vec3 eye = centre + dist * dir;
    const double near = 0.05 * dist;
    const Mat4 view_proj =
        Perspective(tan_y, aspect, near, dist + 4 * radius + 200) * LookAt(eye, -dir, up);
    glViewport(vp.x, vp.y, vp.w, vp.h);
    glScissor(vp.x, vp.y, vp.w, vp.h);
    glEnable(GL_SCISSOR_TEST);
    ClearColourAndDepth(ids_mode, kOverviewBackground);
    glDisable(GL_SCISSOR_TEST);
    glEnable(GL_DEPTH_TEST);
    DrawMeshes(scene, view_proj, eye, false, -dir, 0.0,
               near * std::sqrt(1.0 + tan_y * tan_y * (1.0 + aspect * aspect)), 2.0 * tan_y / vp.h,
               1.0);
  }
};

std::string Renderer::DefaultFontPath() {
  return "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf";
}

Renderer::Renderer(const std::string& font_path) : impl_(std::make_unique<Impl>()) {
  Impl& s = *impl_;
  s.font = std::make_unique<Font>(font_path);
  const int attribs[] = {OSMESA_FORMAT,
                         OSMESA_RGBA,
                         OSMESA_DEPTH_BITS,
                         24,
                         OSMESA_STENCIL_BITS,
                         0,
                         OSMESA_PROFILE,
                         OSMESA_CORE_PROFILE,
                         OSMESA_CONTEXT_MAJOR_VERSION,
                         3,
                         OSMESA_CONTEXT_MINOR_VERSION,
                         3,
                         0};
  s.ctx = OSMesaCreateContextAttribs(attribs, nullptr);
  if (s.ctx == nullptr) {
    throw RenderError(
        "OSMesa could not create an OpenGL 3.3 core context (Debian package libosmesa6)");
  }
  s.MakeCurrent(16, 16);
  if (const char* missing = s.gl.Load()) {
    throw RenderError(std::string("OSMesa lacks the OpenGL entry point ") + missing);
  }
  const GlApi& gl = s.gl;
  auto u = [&](GLuint p, const char* name) { return gl.GetUniformLocation(p, name); };
  for (int p = 0; p < Impl::kPatterns; ++p) {
    const std::string fragment = "#version 330 core\n#define PATTERN " + std::to_string(p) + "\n" +
                                 shaders::kMeshFragmentBody;
    const GLuint prog = s.mesh_prog[p] = Link(gl, shaders::kMeshVertex, fragment.c_str());
    s.mu[p] = {u(prog, "u_view_proj"), u(prog, "u_base"),  u(prog, "u_spec"),
               u(prog, "u_shininess"), u(prog, "u_metal"), u(prog, "u_wet"),
               u(prog, "u_eye"),       u(prog, "u_light"), u(prog, "u_ref2"),
               u(prog, "u_spot_dir"),  u(prog, "u_spot"),  u(prog, "u_ambient"),
               u(prog, "u_exposure"),  u(prog, "u_along"), u(prog, "u_across"),
               u(prog, "u_band"),      u(prog, "u_fade")};
  }
  s.id_prog = Link(gl, shaders::kMeshVertex, shaders::kIdFragment);
  s.id_uniform = u(s.id_prog, "u_id");
  s.id_view_proj = u(s.id_prog, "u_view_proj");
  s.post_prog = Link(gl, shaders::kPostVertex, shaders::kPostFragment);
  s.mask_prog = Link(gl, shaders::kPostVertex, shaders::kMaskFragment);
  auto fan = [&](GLuint p) {
    return Impl::FanUniforms{u(p, "u_fan_center"), u(p, "u_fan_scale"), u(p, "u_fan_inner"),
                             u(p, "u_fan_outer"),  u(p, "u_fan_sides"), u(p, "u_fan_depth")};
  };
  s.post_fan = fan(s.post_prog);
  s.mask_fan = fan(s.mask_prog);
  s.pu = {u(s.post_prog, "u_tex"),       u(s.post_prog, "u_center"),  u(s.post_prog, "u_radius"),
          u(s.post_prog, "u_theta_max"), u(s.post_prog, "u_tan_max"), u(s.post_prog, "u_k"),
          u(s.post_prog, "u_exposure"),  u(s.post_prog, "u_ids")};

  // vertex layout of render::Vertex
  gl.GenVertexArrays(1, &s.vao);
  gl.GenVertexArrays(1, &s.post_vao);
  gl.GenBuffers(1, &s.vbo);
  gl.GenBuffers(1, &s.ebo);
  gl.BindVertexArray(s.vao);
  gl.BindBuffer(GL_ARRAY_BUFFER, s.vbo);
  gl.BindBuffer(GL_ELEMENT_ARRAY_BUFFER, s.ebo);
  const GLsizei stride = sizeof(Vertex);
  gl.VertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, stride,
                         reinterpret_cast<const void*>(offsetof(Vertex, pos)));
  gl.VertexAttribPointer(1, 3, GL_FLOAT, GL_FALSE, stride,
                         reinterpret_cast<const void*>(offsetof(Vertex, normal)));
  gl.VertexAttribPointer(2, 2, GL_FLOAT, GL_FALSE, stride,
                         reinterpret_cast<const void*>(offsetof(Vertex, uv)));
  gl.VertexAttribPointer(3, 1, GL_FLOAT, GL_FALSE, stride,
                         reinterpret_cast<const void*>(offsetof(Vertex, rough)));
  gl.VertexAttribPointer(4, 3, GL_FLOAT, GL_FALSE, stride,
                         reinterpret_cast<const void*>(offsetof(Vertex, tex)));
  for (GLuint i = 0; i < 5; ++i) gl.EnableVertexAttribArray(i);
  gl.BindVertexArray(0);
  if (glGetError() != GL_NO_ERROR) throw RenderError("OpenGL error while setting up the renderer");
}

Renderer::~Renderer() {
  Impl& s = *impl_;
  if (s.ctx == nullptr) return;
  if (s.buf_w > 0 &&
      OSMesaMakeCurrent(s.ctx, s.buffer.data(), GL_UNSIGNED_BYTE, s.buf_w, s.buf_h)) {
    const GlApi& gl = s.gl;
    if (gl.DeleteProgram != nullptr) {
      for (const GLuint prog : s.mesh_prog) gl.DeleteProgram(prog);
      gl.DeleteProgram(s.post_prog);
      gl.DeleteProgram(s.mask_prog);
      gl.DeleteProgram(s.id_prog);
      gl.DeleteVertexArrays(1, &s.vao);
      gl.DeleteVertexArrays(1, &s.post_vao);
      gl.DeleteBuffers(1, &s.vbo);
      gl.DeleteBuffers(1, &s.ebo);
      if (s.fbo != 0) {
        gl.DeleteFramebuffers(1, &s.fbo);
        gl.DeleteRenderbuffers(1, &s.fbo_depth);
        glDeleteTextures(1, &s.fbo_tex);
      }
      if (s.meter_fbo != 0) {
        gl.DeleteFramebuffers(1, &s.meter_fbo);
        glDeleteTextures(1, &s.meter_tex);
      }
    }
  }
  OSMesaDestroyContext(s.ctx);
}

std::string Renderer::GlRenderer() const {
  const GLubyte* r = glGetString(GL_RENDERER);
  return r != nullptr ? reinterpret_cast<const char*>(r) : "";
}

namespace {

void CheckSpec(const ViewSpec& spec) {
  if (spec.width < 16 || spec.height < 16 || spec.width > 8192 || spec.height > 8192) {
    throw std::invalid_argument("render size " + std::to_string(spec.width) + "x" +
                                std::to_string(spec.height) + ": expected 16..8192 pixels");
  }
  if (!(spec.field_stop > 0 && spec.field_stop <= 1) ||
      !(spec.distortion >= 0 && spec.distortion <= 1) || !(spec.light_ref_mm > 0) ||
      !(spec.scope_detail >= 0 && spec.scope_detail <= 1) ||
      !(spec.overview_fov_deg > 1 && spec.overview_fov_deg < 170) ||
      !(spec.exposure > 0 && spec.exposure < 1e3)) {
    throw std::invalid_argument(
        "ViewSpec: expected field_stop in (0,1], distortion in [0,1], scope_detail in [0,1], "
        "light_ref_mm > 0, overview_fov_deg in (1,170), exposure in (0,1000)");
  }
}

}  // namespace

void Renderer::Draw(const Scene& scene, const ViewSpec& spec, bool ids) {
  CheckSpec(spec);
  Impl& s = *impl_;
  const int w = spec.width, h = spec.height;
  s.MakeCurrent(w, h);
  s.ids_mode = ids;
  glPixelStorei(GL_PACK_ALIGNMENT, 1);
  glDisable(GL_CULL_FACE);
  glDepthFunc(GL_LESS);
  s.gl.BindFramebuffer(GL_FRAMEBUFFER, 0);
  glViewport(0, 0, w, h);
  glDisable(GL_SCISSOR_TEST);
  glClearColor(0, 0, 0, 1);
  glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
  s.Upload(scene);

  switch (spec.view) {
    case View::kScope:
      s.RenderScope(scene, spec, {0, 0, w, h});
      break;
    case View::kOverview:
      s.RenderOverview(scene, spec, {0, 0, w, h});
      break;
    case View::kBoth:
      s.RenderScope(scene, spec, {0, 0, w / 2, h});
      s.RenderOverview(scene, spec, {w / 2, 0, w - w / 2, h});
      break;
  }
  s.ids_mode = false;
  glFinish();
  if (const GLenum err = glGetError(); err != GL_NO_ERROR) {
    throw RenderError("OpenGL error " + std::to_string(err) + " while rendering");
  }
}

void Renderer::Render(const Scene& scene, const ViewSpec& spec, Image* out) {
  Draw(scene, spec, false);
  // OSMesa's colour buffer is our own `buffer` (bottom-up RGBA), complete after glFinish: no
  // glReadPixels copy. Store top-down RGB.
  const Impl& s = *impl_;
  const int w = spec.width, h = spec.height;
  out->Resize(w, h);
  for (int y = 0; y < h; ++y) {
    const unsigned char* src = s.buffer.data() + static_cast<std::size_t>(4) * w * (h - 1 - y);
    std::uint8_t* dst = out->At(0, y);
    for (int x = 0; x < w; ++x) {
      dst[3 * x] = src[4 * x];
      dst[3 * x + 1] = src[4 * x + 1];
      dst[3 * x + 2] = src[4 * x + 2];
    }
  }
  if (spec.overlay && scene.overlay.enabled) DrawOverlay(scene.overlay, s.font.get(), out);
}

void Renderer::RenderIds(const Scene& scene, const ViewSpec& spec, std::vector<std::int32_t>* ids) {
  Draw(scene, spec, true);
  const Impl& s = *impl_;
  const int w = spec.width, h = spec.height;
  ids->assign(static_cast<std::size_t>(w) * h, -1);
  for (int y = 0; y < h; ++y) {
    const unsigned char* src = s.buffer.data() + static_cast<std::size_t>(4) * w * (h - 1 - y);
    for (int x = 0; x < w; ++x) {
      (*ids)[static_cast<std::size_t>(y) * w + x] = src[4 * x] + 256 * src[4 * x + 1] - 1;
    }
  }
}

double Renderer::LastExposure() const { return impl_->last_exposure; }

bool InFieldStop(const ViewSpec& spec, int x, int y) {
  const int vw = spec.view == View::kBoth ? spec.width / 2 : spec.width;
  if (spec.view == View::kOverview || x < 0 || x >= vw || y < 0 || y >= spec.height) return false;
  const double r = 0.5 * spec.field_stop * std::min(vw, spec.height) - 1.0;
  const double dx = x + 0.5 - 0.5 * vw, dy = y + 0.5 - 0.5 * spec.height;
  return dx * dx + dy * dy < r * r;
}

double ClippedShare(const Image& image, const ViewSpec& spec) {
  if (image.width != spec.width || image.height != spec.height) {
    throw std::invalid_argument("ClippedShare: image size differs from the ViewSpec");
  }
  std::size_t inside = 0, clipped = 0;
  for (int y = 0; y < image.height; ++y) {
    for (int x = 0; x < image.width; ++x) {
      if (!InFieldStop(spec, x, y)) continue;
      const std::uint8_t* p = image.At(x, y);
      ++inside;
      clipped += std::max({p[0], p[1], p[2]}) >= kClippedLevel;
    }
  }
  return inside == 0 ? 0.0 : static_cast<double>(clipped) / static_cast<double>(inside);
}

}  // namespace arthrosim::render
