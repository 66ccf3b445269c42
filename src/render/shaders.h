#pragma once
// GLSL 330 core sources of the renderer.

namespace arthrosim::render::shaders {

// Meshes: world-space positions; lighting in world space. a_tex: texture-space position (mm),
// the rest position of soft tissue so its pattern stays on the tissue as it deforms.
inline constexpr const char* kMeshVertex = R"(#version 330 core
layout(location = 0) in vec3 a_pos;
layout(location = 1) in vec3 a_normal;
layout(location = 2) in vec2 a_uv;
layout(location = 3) in float a_rough;
layout(location = 4) in vec3 a_tex;
uniform mat4 u_view_proj;
out vec3 v_pos;
out vec3 v_normal;
out vec2 v_uv;
out float v_rough;
out vec3 v_tex;
void main() {
  v_pos = a_pos;
  v_normal = a_normal;
  v_uv = a_uv;
  v_rough = a_rough;
  v_tex = a_tex;
  gl_Position = u_view_proj * vec4(a_pos, 1.0);
}
)";

// Blinn-Phong under one point light plus a sharp wet-film lobe (u_wet). Scope: the light sits at
// the lens with inverse-square fall-off (u_ref2 = reference distance squared) and a soft cone
// around the view axis; overview: a headlight without fall-off (u_ref2 = 0). u_exposure > 0:
// tone-mapped output with that gain (overview); 0: linear radiance for the lens pass, which
// exposes the frame from its own content (scope auto-exposure). PATTERN (a #define put in front
// of this body, one program per pattern): 0 plain, 1 braided suture, 2 bone (uv.x = albedo grain
// factor; cancellous bed only where burred), 3 fibrous (tendon, muscle: bundles along the fibre
// axis, u_along / u_across* in radians per mm), 4 vascular (bursa, synovium). Soft-tissue
// patterns (0, 3, 4) show electrocautery marks (rough = 1 per marked vertex): a charred core in a
// blanched rim. One program per pattern because llvmpipe runs both sides of a branch under a
// lane mask: a runtime pattern switch shaded every fragment with the noise.
inline constexpr const char* kMeshFragmentBody = R"(
in vec3 v_pos;
in vec3 v_normal;
in vec2 v_uv;
in float v_rough;
in vec3 v_tex;
uniform vec3 u_base;
uniform float u_spec;
uniform float u_shininess;
uniform float u_metal;
uniform float u_wet;
uniform vec3 u_eye;
uniform vec3 u_light;
uniform float u_ref2;
uniform vec3 u_spot_dir;
uniform int u_spot;
uniform float u_ambient;
uniform float u_exposure;
uniform vec3 u_along;
uniform float u_across;
uniform float u_band;
uniform float u_fade;
out vec4 o_color;

#if PATTERN == 2
float Hash(vec3 p) {
  p = fract(p * 0.3183099 + vec3(0.71, 0.113, 0.419));
  p *= 17.0;
  return fract(p.x * p.y * p.z * (p.x + p.y + p.z));
}
float Noise(vec3 x) {
  vec3 i = floor(x);
  vec3 f = fract(x);
  f = f * f * (3.0 - 2.0 * f);
  return mix(mix(mix(Hash(i), Hash(i + vec3(1, 0, 0)), f.x),
                 mix(Hash(i + vec3(0, 1, 0)), Hash(i + vec3(1, 1, 0)), f.x), f.y),
             mix(mix(Hash(i + vec3(0, 0, 1)), Hash(i + vec3(1, 0, 1)), f.x),
                 mix(Hash(i + vec3(0, 1, 1)), Hash(i + vec3(1, 1, 1)), f.x), f.y), f.z);
}
#endif

void main() {
  vec3 n = normalize(v_normal);
  vec3 view = normalize(u_eye - v_pos);
  if (dot(n, view) < 0.0) n = -n;  // two-sided: cut faces, thin blades, open tubes
  vec3 albedo = u_base;
  float spec = u_spec;
  float wet = u_wet;
#if PATTERN == 1
  // braid: two helices of white tracer over the blue
  float a = fract(v_uv.x * 0.5 + v_uv.y * 2.0);
  float b = fract(v_uv.x * 0.5 - v_uv.y * 2.0);
  if (a < 0.16 || b < 0.08) albedo = vec3(0.93, 0.93, 0.90);
#elif PATTERN == 2
  albedo *= v_uv.x;  // per-vertex grain (BuildScene), cheaper than per-fragment noise
  if (v_rough > 0.0) {
    // burred (decorticated): cancellous bone, pitted, bleeding from the opened marrow spaces
    float pits = Noise(v_tex * 5.0);
    vec3 cancellous = vec3(0.80, 0.50, 0.40) * (0.65 + 0.35 * pits);
    cancellous = mix(cancellous, vec3(0.55, 0.08, 0.07), smoothstep(0.55, 0.8, pits));
    albedo = mix(albedo, cancellous, v_rough);
    spec *= 1.0 - 0.8 * v_rough;
    vec3 jitter = vec3(Noise(v_tex * 4.0), Noise(v_tex * 4.0 + 17.0), Noise(v_tex * 4.0 + 31.0));
    n = normalize(n + v_rough * 0.6 * (jitter - 0.5));
  }
#elif PATTERN == 3
  // fibre bundles: streaks along the fibre axis (u_along, radians per mm of the crimp), spaced
  // across it within this face (u_across = radians per mm), wavy with the crimp; faded where the
  // spacing nears a pixel (u_fade)
  vec3 across = cross(u_along, v_normal);
  float la = length(across);
  if (la > 1e-6) {
    float s = dot(v_tex, u_along);
    float x = dot(v_tex, across) * (u_across / la);
    float crimp = 0.9 * sin(s) + 0.4 * sin(2.7 * s + 1.3);
    float fib = 0.6 * sin(x + crimp) + 0.4 * sin(2.3 * x + 1.7 * sin(0.5 * s) + 0.6 * crimp);
    float fade = clamp(2.0 - length(u_eye - v_pos) * u_fade, 0.0, 1.0);
    albedo *= 1.0 + u_band * fade * fib;
  }
#elif PATTERN == 4
  // vessels: two families of meandering lines (zero sets of warped sines), dark red
  vec3 q = v_tex * 0.3;
  float l1 = abs(sin(2.1 * q.x + 1.7 * sin(1.3 * q.y + 0.8 * sin(1.9 * q.z))));
  float l2 = abs(sin(2.7 * q.y + 1.3 * sin(1.1 * q.z + 0.9 * sin(2.3 * q.x)) + 1.0));
  float vessel = max(1.0 - smoothstep(0.0, 0.09, l1), 0.75 * (1.0 - smoothstep(0.0, 0.06, l2)));
  albedo = mix(albedo, vec3(0.42, 0.04, 0.05), vessel);
#endif
#if PATTERN == 0 || PATTERN == 3 || PATTERN == 4
  if (v_rough > 0.0) {
    // electrocautery mark: blanched rim, charred core, dry
    albedo = mix(albedo, vec3(0.84, 0.76, 0.64), 0.8 * smoothstep(0.0, 0.5, v_rough));
    albedo = mix(albedo, vec3(0.13, 0.09, 0.07), 0.9 * smoothstep(0.5, 1.0, v_rough));
    spec *= 1.0 - 0.8 * v_rough;
    wet *= 1.0 - v_rough;
  }
#endif
  vec3 to_light = u_light - v_pos;
  float d2 = max(dot(to_light, to_light), 1e-6);
  vec3 l = to_light * inversesqrt(d2);
  float irradiance = u_ref2 > 0.0 ? min(u_ref2 / d2, 16.0) : 1.0;
  if (u_spot != 0) {
    float c = max(dot(-l, u_spot_dir), 0.0);
    irradiance *= 0.3 + 0.7 * c * c;
  }
  float diffuse = max(dot(n, l), 0.0);
  vec3 h = normalize(l + view);
  // Schlick's rational form of pow(t, shininess): same highlight, far cheaper on llvmpipe
  float t = max(dot(n, h), 0.0);
  float highlight = spec * t / (u_shininess - u_shininess * t + t);
  // the saline film: a mirror-like glint of the light
  highlight += wet * t / (600.0 - 600.0 * t + t);
  vec3 spec_color = mix(vec3(1.0), albedo, u_metal);
  vec3 color = albedo * (u_ambient + irradiance * diffuse) + irradiance * highlight * spec_color;
  o_color = u_exposure > 0.0 ? vec4(1.0 - exp(-1.4 * u_exposure * color), 1.0) : vec4(color, 1.0);
}
)";

// Regular polygons without vertex data, around u_fan_center (NDC) with u_fan_scale NDC per
// radius unit. Fan (u_fan_outer = 0; sides + 2 vertices): vertex 0 the centre, then the corners
// at radius u_fan_inner. Ring (triangle strip, 2 sides + 2 vertices): alternately radius
// u_fan_inner and u_fan_outer, i.e. everything between the polygon and the outer one.
inline constexpr const char* kPostVertex = R"(#version 330 core
uniform vec2 u_fan_center;
uniform vec2 u_fan_scale;
uniform float u_fan_inner;
uniform float u_fan_outer;
uniform int u_fan_sides;
uniform float u_fan_depth;
void main() {
  int corner;
  float r;
  if (u_fan_outer > 0.0) {
    corner = gl_VertexID / 2;
    r = gl_VertexID % 2 == 0 ? u_fan_inner : u_fan_outer;
  } else {
    corner = gl_VertexID - 1;
    r = gl_VertexID == 0 ? 0.0 : u_fan_inner;
  }
  float a = 6.2831853 * float(corner % u_fan_sides) / float(u_fan_sides);
  gl_Position = vec4(u_fan_center + r * u_fan_scale * vec2(cos(a), sin(a)), u_fan_depth, 1.0);
}
)";

// Depth-only pass (colour writes off).
inline constexpr const char* kMaskFragment = R"(#version 330 core
out vec4 o_color;
void main() { o_color = vec4(0.0); }
)";

// Scope optics: the rectilinear render (half-angle u_theta_max at the texture edge, linear
// radiance) is remapped to the image circle, blending rectilinear (k = 0) with an equidistant
// fisheye (k = 1: barrel distortion), exposed with u_exposure and tone-mapped; black outside the
// field stop with a one-pixel anti-aliased rim. u_exposure = 0: the linear radiance (the
// metering pass). u_ids = 1: tissue ids, nearest texel, no vignetting, hard rim.
inline constexpr const char* kPostFragment = R"(#version 330 core
uniform sampler2D u_tex;
uniform vec2 u_center;
uniform float u_radius;
uniform float u_theta_max;
uniform float u_tan_max;
uniform float u_k;
uniform float u_exposure;
uniform int u_ids;
out vec4 o_color;
void main() {
  vec2 d = gl_FragCoord.xy - u_center;
  float len = length(d);
  float inside = clamp(u_radius - len + 0.5, 0.0, 1.0);
  if (inside <= 0.0 || (u_ids != 0 && len > u_radius)) {
    o_color = vec4(0.0, 0.0, 0.0, 1.0);
    return;
  }
  float r = min(len / u_radius, 1.0);
  float rho = mix(r, tan(r * u_theta_max) / u_tan_max, u_k);
  vec2 dir = len > 0.0 ? d / len : vec2(0.0);
  vec2 uv = vec2(0.5) + 0.5 * rho * dir;
  if (u_ids != 0) {
    ivec2 size = textureSize(u_tex, 0);
    o_color = texelFetch(u_tex, clamp(ivec2(uv * vec2(size)), ivec2(0), size - 1), 0);
    return;
  }
  // one level, same filter for min and mag: an explicit LOD spares llvmpipe the derivatives
  vec3 c = textureLod(u_tex, uv, 0.0).rgb;
  c *= 1.0 - 0.25 * r * r * r * r;  // rim vignetting of the rod-lens optics
  if (u_exposure > 0.0) c = 1.0 - exp(-1.4 * u_exposure * c);
  o_color = vec4(c * inside, 1.0);
}
)";

// Tissue ids: the mesh index + 1 in 8-bit red and green (0 = no mesh).
inline constexpr const char* kIdFragment = R"(#version 330 core
uniform vec3 u_id;
out vec4 o_color;
void main() { o_color = vec4(u_id, 1.0); }
)";

}  // namespace arthrosim::render::shaders
