#pragma once
// Off-screen OpenGL renderer on OSMesa (Mesa llvmpipe, 4.5 core context, GLSL 330 core).
// One Renderer owns one context and must be used from one thread. Output is deterministic for a
// fixed LP_NUM_THREADS (set it before the first Renderer is created; tests pin it).
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "arthrosim/render/image.h"
#include "arthrosim/render/scene.h"

namespace arthrosim::render {

/// Which camera(s) to draw.
enum class View : std::uint8_t {
  kScope,     ///< arthroscope: oblique lens, circular field stop, scope light
  kOverview,  ///< external camera framing the bones, headlight
  kBoth,      ///< scope left half, overview right half
};

/// Parses "scope" / "overview" / "both". @throws std::invalid_argument otherwise.
View ParseView(const std::string& name);
/// Lower-case name of a view.
const char* ViewName(View view);

/// How to draw one image.
struct ViewSpec {
  View view = View::kScope;
  int width = 640;             ///< output pixels (>= 16)
  int height = 480;            ///< output pixels (>= 16)
  double field_stop = 0.95;    ///< image-circle diameter / image height, in (0, 1]
  double distortion = 1.0;     ///< 0 rectilinear ... 1 equidistant fisheye (barrel)
  double scope_detail = 0.25;  ///< 0 scope texture = image circle ... 1 matches the centre
                               ///< magnification of the fisheye (sharper, ~2x the pixels)
  double light_ref_mm = 20.0;  ///< distance at which the scope light gives unit irradiance
  /// Scope view: the camera's automatic exposure, a gain metered from each frame's own content
  /// (mean luminance of the image circle to mid grey unless its 98.5th-percentile channel would
  /// come within 3 % of white), so near surfaces keep their brightness instead of saturating.
  bool auto_exposure = true;
  double exposure = 1.0;         ///< scope gain when auto_exposure is off, in (0, 1000)
  double overview_fov_deg = 35;  ///< vertical field of view of the overview camera
  bool overlay = true;           ///< draw time, tools, force bars and plan text
};

/// Owns the OSMesa context, shaders and buffers.
class Renderer {
 public:
  /// Creates the context. `font_path` is the TrueType font of the overlay.
  /// @throws RenderError if OSMesa cannot create a 4.5 core context or the font is missing.
  explicit Renderer(const std::string& font_path = DefaultFontPath());
  ~Renderer();
  Renderer(const Renderer&) = delete;
  Renderer& operator=(const Renderer&) = delete;

  /// Draws `scene` as seen by `spec` into `out` (resized to spec.width x spec.height).
  /// @throws std::invalid_argument on a bad spec, RenderError on a GL failure.
  void Render(const Scene& scene, const ViewSpec& spec, Image* out);

  /// Draws which mesh covers each pixel, as `Render` would draw `scene` (no overlay): row-major
  /// top-down spec.width x spec.height indices into scene.meshes, -1 where no mesh is (fluid,
  /// background, outside the field stop). @throws like Render.
  void RenderIds(const Scene& scene, const ViewSpec& spec, std::vector<std::int32_t>* ids);

  /// Exposure gain of the scope image last drawn (spec.exposure when auto exposure is off).
  double LastExposure() const;

  /// GL_RENDERER string of the context (e.g. "llvmpipe (LLVM 15.0.6, 256 bits)").
  std::string GlRenderer() const;

  /// DejaVu Sans from the Debian package fonts-dejavu-core.
  static std::string DefaultFontPath();

 private:
  void Draw(const Scene& scene, const ViewSpec& spec, bool ids);
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Channel level counted as clipped (of 255).
inline constexpr int kClippedLevel = 250;

/// True if pixel (x, y) (top-down) lies inside the scope's field stop (1 px within its rim) in an
/// image drawn with `spec` (the left half for View::kBoth; never for View::kOverview).
bool InFieldStop(const ViewSpec& spec, int x, int y);

/// Share of the pixels inside the field stop with any channel >= kClippedLevel, in [0, 1].
/// @throws std::invalid_argument if the image size differs from spec's.
double ClippedShare(const Image& image, const ViewSpec& spec);

}  // namespace arthrosim::render
