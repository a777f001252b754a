// renderer_impl.h — the renderer's internals shared by its passes:
// renderer.cpp (context, framebuffer, the visible set) and refine.cpp (the
// refinement levels of voxvis/refine.h).
#pragma once

#include <array>
#include <chrono>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include <glm/glm.hpp>

#define GL_GLEXT_PROTOTYPES 1
#include <GL/glcorearb.h>

#include "egl_context.h"
#include "refine_state.h"
#include "voxvis/render.h"

namespace voxvis::render::detail {

using Clock = std::chrono::steady_clock;
inline double ms_since(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

/// One object as the vertex shader reads it (32 bytes).
struct Instance {
  float centre[3];
  float kind;  // 0 ball, 1 box.
  float half[3];
  std::uint32_t index;  // Instance number + 1; 0 in the id buffer is "nothing".
};
static_assert(sizeof(Instance) == 32);

/// The camera's frame: f along the view, right and up across it, as the CPU
/// ray caster builds it (voxvis/raycast.h).
struct Basis {
  glm::dvec3 eye, f, right, up;
  double tanx = 1.0, tany = 1.0, near = 0.05, far = 1000.0;
};

inline bool make_basis(const Camera& cam, Basis* b, std::string* error) {
  auto finite3 = [](const Vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); };
  if (!finite3(cam.eye) || !finite3(cam.dir) || !finite3(cam.up) || !std::isfinite(cam.fov_y_deg) ||
      !std::isfinite(cam.aspect) || !std::isfinite(cam.near) || !std::isfinite(cam.far)) {
    *error = "camera: a value is not finite";
    return false;
  }
  if (!(cam.fov_y_deg > 0.0 && cam.fov_y_deg < 180.0)) {
    *error = "camera: fov_y_deg must be in (0, 180)";
    return false;
  }
  if (!(cam.aspect > 0.0) || !(cam.near > 0.0) || !(cam.far > cam.near)) {
    *error = "camera: needs aspect > 0 and 0 < near < far";
    return false;
  }
  if (cam.far > 1e30) {
    *error = "camera: far beyond 1e30 cannot be rendered in single precision";
    return false;
  }
  const double dl = glm::length(cam.dir);
  if (!(dl > 0.0)) {
    *error = "camera: dir is zero";
    return false;
  }
  b->f = cam.dir / dl;
  const glm::dvec3 r = glm::cross(b->f, cam.up);
  const double rl = glm::length(r);
  if (!(rl > 1e-12 * glm::length(cam.up))) {
    *error = "camera: up is parallel to dir";
    return false;
  }
  b->right = r / rl;
  b->up = glm::cross(b->right, b->f);
  b->eye = cam.eye;
  b->tany = std::tan(cam.fov_y_deg * (3.14159265358979323846 / 360.0));
  b->tanx = cam.aspect * b->tany;
  b->near = cam.near;
  b->far = cam.far;
  return true;
}

/// Whether the object may meet the frustum: rejected only when it lies wholly
/// on the outer side of one of the six planes (conservative; a sphere is
/// tested as a ball, a box as a box).
inline bool may_meet_frustum(const Basis& b, const ObjectDesc& o) {
  const glm::dvec3 c = o.center - b.eye;
  const glm::dvec3 h = o.shape == Shape::Sphere ? glm::dvec3(o.radius) : o.half_extent;
  // Planes as n . p <= k with p relative to the eye.
  const std::array<std::pair<glm::dvec3, double>, 6> planes = {{
      {b.right - b.tanx * b.f, 0.0},
      {-b.right - b.tanx * b.f, 0.0},
      {b.up - b.tany * b.f, 0.0},
      {-b.up - b.tany * b.f, 0.0},
      {-b.f, -b.near},
      {b.f, b.far},
  }};
  for (const auto& [n, k] : planes) {
    const double reach = o.shape == Shape::Sphere ? o.radius * glm::length(n)
                                                  : std::abs(n.x) * h.x + std::abs(n.y) * h.y + std::abs(n.z) * h.z;
    const double least = glm::dot(n, c) - reach;
    const double tol = 1e-9 * (glm::length(c) * glm::length(n) + reach + std::abs(k)) + 1e-300;
    if (least > k + tol) return false;
  }
  return true;
}

/// Indices of the unit cube's twelve triangles (renderer.cpp's kTriangles):
/// every object and box is drawn as one instance of them.
constexpr GLsizei kBoxIndices = 36;
constexpr int kFlushEvery = 512;  // Queries between flushes (long unflushed batches misreport on llvmpipe).
constexpr std::int64_t kMaxPixels = std::int64_t{1} << 26;  // 64 Mpixel: 512 MiB of id and depth.

}  // namespace voxvis::render::detail

namespace voxvis::render {

struct Renderer::Impl {
  std::unique_ptr<detail::EglContext> egl;
  ContextInfo info;
  GLuint program = 0, vao = 0, corner_vbo = 0, index_ebo = 0, instance_vbo = 0;
  GLuint fbo = 0, id_rb = 0, depth_rb = 0;
  GLint u_right = -1, u_up = -1, u_f = -1, u_tan = -1, u_size = -1, u_range = -1;
  int width = 0, height = 0;
  std::size_t instance_capacity = 0;
  std::vector<GLuint> queries;
  std::vector<detail::Instance> instances;
  std::vector<ObjectId> drawn_ids;  // Instance number -> id.
  std::vector<ObjectId> ids;        // Last id image.
  std::vector<std::uint32_t> raw;
  detail::RefineState refine;      // The refinement levels' state between frames.

  ~Impl() {
    if (!egl) return;
    std::string ignored;
    if (egl->make_current(&ignored)) {
      if (!queries.empty()) glDeleteQueries(static_cast<GLsizei>(queries.size()), queries.data());
      glDeleteFramebuffers(1, &fbo);
      glDeleteRenderbuffers(1, &id_rb);
      glDeleteRenderbuffers(1, &depth_rb);
      glDeleteBuffers(1, &corner_vbo);
      glDeleteBuffers(1, &index_ebo);
      glDeleteBuffers(1, &instance_vbo);
      glDeleteVertexArrays(1, &vao);
      glDeleteProgram(program);
    }
  }

  bool setup(std::string* error);
  bool resize(int w, int h, std::string* error);
  /// Checks the resolution and camera, makes the context current and sizes
  /// the framebuffer.
  bool begin(const Camera& cam, int w, int h, detail::Basis* b, std::string* error);
  /// An instance of a ball or box relative to the eye, numbered `index`.
  static detail::Instance instance(const detail::Basis& b, const Vec3& centre, const Vec3& half, bool box,
                                   std::uint32_t index);
  /// Uploads `instances`.
  void upload();
  /// Clears the framebuffer and draws the first `count` instances (ids and
  /// depth; all when count is -1), with the camera's uniforms; one draw call.
  void depth_pass(const detail::Basis& b, int w, int h, std::ptrdiff_t count = -1);
  /// Query state: depth test LEQUAL, no writes; queries for `n` probes.
  void begin_probes(std::size_t n);
  /// Draws instance k alone inside query q (GL_SAMPLES_PASSED or
  /// GL_ANY_SAMPLES_PASSED), flushing every kFlushEvery.
  void probe(GLenum target, std::size_t q, std::size_t k);
  void end_probes();
  /// Near-optimal's cost model, loaded or measured on first use (cost_model.cpp).
  bool ensure_model(std::string* note, std::string* error);
  bool gl_ok(const char* what, std::string* error) {
    const GLenum e = glGetError();
    if (e == GL_NO_ERROR) return true;
    char code[16];
    std::snprintf(code, sizeof code, "0x%04x", e);
    *error = std::string("OpenGL error ") + code + " in " + what;
    return false;
  }
};

}  // namespace voxvis::render
