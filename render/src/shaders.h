// shaders.h — the GLSL of the exact-object pass. Every ball and box is drawn
// as its bounding box (back faces only, so that a box containing the eye
// still covers the view), and the fragment shader intersects the ray through
// the pixel centre with the object itself: a closed ball or box, clipped to
// [near, far] as the CPU ray caster does. It writes the entry depth as
// t / far and the object's instance number. A mesh is drawn as its triangles
// (kMeshVertexShader, kMeshFragmentShader), both faces, with the same depth.
#pragma once

namespace voxvis::render::detail {

inline constexpr const char* kVertexShader = R"(#version 420 core
layout(location = 0) in vec3 corner;   // A corner of the cube [-1, 1]^3.
layout(location = 1) in vec4 centre;   // xyz: centre - eye, world axes; w: 0 ball, 1 box, 2 mesh.
layout(location = 2) in vec3 half_ext; // Half extents (the radius thrice for a ball).
layout(location = 3) in uint index;    // Instance number + 1.
uniform vec3 u_right;
uniform vec3 u_up;
uniform vec3 u_f;
uniform vec2 u_tan;  // tan of the half angles, x then y.
flat out vec3 v_centre;
flat out vec3 v_half;
flat out float v_kind;
flat out uint v_index;
void main() {
  // The proxy is grown a little so that rounding of its corners never drops
  // a pixel centre the object covers; the fragment test is exact.
  vec3 grow = half_ext * 1e-4 + vec3(1e-6 * length(centre.xyz) + 1e-30);
  vec3 p = centre.xyz + corner * (half_ext + grow);
  gl_Position = vec4(dot(p, u_right) / u_tan.x, dot(p, u_up) / u_tan.y, 0.0, dot(p, u_f));
  // A mesh's triangles are drawn by the mesh pass: here its proxy lies
  // wholly beyond the clip plane x = w, so it yields no fragment.
  if (centre.w > 1.5) gl_Position = vec4(2.0, 0.0, 0.0, 1.0);
  v_centre = centre.xyz;
  v_half = half_ext;
  v_kind = centre.w;
  v_index = index;
}
)";

inline constexpr const char* kFragmentShader = R"(#version 420 core
flat in vec3 v_centre;
flat in vec3 v_half;
flat in float v_kind;
flat in uint v_index;
uniform vec3 u_right;
uniform vec3 u_up;
uniform vec3 u_f;
uniform vec2 u_tan;
uniform vec2 u_size;   // Viewport, pixels.
uniform vec2 u_range;  // near, far.
layout(location = 0) out uint o_id;
void main() {
  // The ray through the pixel centre, d . f = 1, so t is a depth.
  vec2 ndc = gl_FragCoord.xy * (2.0 / u_size) - 1.0;
  vec3 d = u_f + (ndc.x * u_tan.x) * u_right + (ndc.y * u_tan.y) * u_up;
  float t0, t1;
  if (v_kind < 0.5) {
    // Along the unit direction the ball is entered at tc - s: the closest
    // approach h comes from a cross product, free of the cancellation of the
    // quadratic's discriminant for small distant balls.
    float len = length(d);
    vec3 dn = d / len;
    float tc = dot(dn, v_centre);
    vec3 c = cross(dn, v_centre);
    float r = v_half.x;
    float s2 = r * r - dot(c, c);
    if (s2 < 0.0) discard;
    float s = sqrt(s2);
    t0 = (tc - s) / len;
    t1 = (tc + s) / len;
  } else {
    t0 = -uintBitsToFloat(0x7F800000u);  // -infinity
    t1 = uintBitsToFloat(0x7F800000u);
    for (int a = 0; a < 3; ++a) {
      float lo = v_centre[a] - v_half[a], hi = v_centre[a] + v_half[a];
      if (d[a] == 0.0) {
        if (lo > 0.0 || hi < 0.0) discard;  // The eye's line misses the slab.
        continue;
      }
      float ta = lo / d[a], tb = hi / d[a];
      t0 = max(t0, min(ta, tb));
      t1 = min(t1, max(ta, tb));
    }
    if (t0 > t1) discard;
  }
  float t = max(t0, u_range.x);
  if (t1 < u_range.x || t > u_range.y) discard;
  gl_FragDepth = t / u_range.y;
  o_id = v_index;
}
)";

// The mesh pass: the triangles themselves, rasterized at the pixel centres
// (the fill rule gives a pixel centre on an edge shared by two triangles to
// exactly one of them, so no ray passes between them), with no face culled.
// The clip-space w of a point is its depth t along the view (as for the
// proxies), so 1 / gl_FragCoord.w, interpolated perspective-correctly, is the
// depth of the triangle's point on the ray through the pixel centre: hits
// are clipped to [near, far] as the ray caster clips a mesh's crossings (a
// mesh is a surface: what is cut off by the near plane neither shows nor
// hides). Coordinates relative to the eye, as the proxies'.
inline constexpr const char* kMeshVertexShader = R"(#version 420 core
layout(location = 0) in vec3 vertex;  // Model units, from the centre of the mesh's model box.
layout(location = 1) in vec3 offset;  // Where that centre goes, relative to the eye, world axes.
layout(location = 2) in vec3 axis0;   // scale * rotation, by columns.
layout(location = 3) in vec3 axis1;
layout(location = 4) in vec3 axis2;
layout(location = 5) in uint index;   // Instance number + 1.
uniform vec3 u_right;
uniform vec3 u_up;
uniform vec3 u_f;
uniform vec2 u_tan;
flat out uint v_index;
invariant gl_Position;  // The same depth in the depth pass and in a query.
void main() {
  vec3 p = offset + mat3(axis0, axis1, axis2) * vertex;
  gl_Position = vec4(dot(p, u_right) / u_tan.x, dot(p, u_up) / u_tan.y, 0.0, dot(p, u_f));
  v_index = index;
}
)";

inline constexpr const char* kMeshFragmentShader = R"(#version 420 core
flat in uint v_index;
uniform vec2 u_range;  // near, far.
layout(location = 0) out uint o_id;
void main() {
  float t = 1.0 / gl_FragCoord.w;
  if (t < u_range.x || t > u_range.y) discard;
  gl_FragDepth = t / u_range.y;
  o_id = v_index;
}
)";

}  // namespace voxvis::render::detail
