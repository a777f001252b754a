// renderer_impl.h — the renderer's internals shared by its passes:
// renderer.cpp (context, framebuffer, the visible set), mesh_pass.cpp (the
// triangles of mesh objects) and refine.cpp (the refinement levels of
// voxvis/refine.h).
#pragma once

#include <array>
#include <chrono>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <initializer_list>
#include <memory>
#include <string>
#include <utility>
#include <unordered_map>
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

/// The kinds of Instance::kind.
constexpr float kBall = 0.0f, kBox = 1.0f, kMesh = 2.0f;

/// One object as the vertex shader reads it (32 bytes). A mesh's instance
/// holds its world box and draws nothing in the ball-and-box pass; its
/// triangles are drawn by the mesh pass (MeshInstance).
struct Instance {
  float centre[3];
  float kind;  // kBall, kBox or kMesh.
  float half[3];
  std::uint32_t index;  // Instance number + 1; 0 in the id buffer is "nothing".
};
static_assert(sizeof(Instance) == 32);

/// A mesh's triangles on the GPU, made on the first frame that draws the
/// mesh and kept while it lives (Renderer::Impl::gpu_mesh): its vertices as
/// floats relative to the centre of its model box (a mesh far from its model
/// origin keeps its precision), its indices, and a vertex array that reads
/// them with the mesh instances.
struct GpuMesh {
  std::weak_ptr<const Mesh> mesh;
  GLuint vao = 0, vbo = 0, ebo = 0;
  GLsizei indices = 0;
  glm::dvec3 centre{0.0};  ///< Centre of the model box, model units.
};

/// One mesh object as the mesh pass's vertex shader reads it (52 bytes).
struct MeshInstance {
  float offset[3];      ///< Where the model box's centre goes, relative to the eye, world units.
  float axes[9];        ///< scale * rotation, column by column.
  std::uint32_t index;  ///< Instance number + 1, as Instance::index.
};
static_assert(sizeof(MeshInstance) == 52);

/// The instances of one mesh this frame: mesh instances [first, first +
/// count), the greatest instance number among them `last`.
struct MeshGroup {
  const GpuMesh* mesh = nullptr;
  std::uint32_t first = 0, count = 0;
  std::size_t last = 0;
};

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

/// Whether the ball (radius half.x) or the box (half extents `half`) about
/// `centre` may meet the frustum: rejected only when it lies wholly on the
/// outer side of one of the six planes (conservative).
inline bool may_meet_frustum(const Basis& b, const glm::dvec3& centre, const glm::dvec3& half, bool ball) {
  const glm::dvec3 c = centre - b.eye;
  const glm::dvec3& h = half;
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
    const double reach = ball ? h.x * glm::length(n) : std::abs(n.x) * h.x + std::abs(n.y) * h.y + std::abs(n.z) * h.z;
    const double least = glm::dot(n, c) - reach;
    const double tol = 1e-9 * (glm::length(c) * glm::length(n) + reach + std::abs(k)) + 1e-300;
    if (least > k + tol) return false;
  }
  return true;
}

/// The same for a sphere (as a ball) or a box (a mesh: by its box,
/// Renderer::Impl::add_object).
inline bool may_meet_frustum(const Basis& b, const ObjectDesc& o) {
  const bool ball = o.shape == Shape::Sphere;
  return may_meet_frustum(b, o.center, ball ? glm::dvec3(o.radius) : o.half_extent, ball);
}

/// Compiles and links a program of the two shaders; 0 with `error` on failure.
GLuint link_program(const char* vertex, const char* fragment, std::string* error);
/// The same for any stages (type, source), a compute shader alone included.
GLuint link_stages(std::initializer_list<std::pair<GLenum, const char*>> stages, std::string* error);

/// Indices of the unit cube's twelve triangles (renderer.cpp's kTriangles):
/// every ball, box and query box is drawn as one instance of them (a mesh's
/// instance too, as nothing: its triangles are the mesh pass's).
constexpr GLsizei kBoxIndices = 36;
constexpr int kFlushEvery = 512;  // Queries between flushes (long unflushed batches misreport on llvmpipe).
constexpr std::int64_t kMaxPixels = std::int64_t{1} << 26;  // 64 Mpixel: 512 MiB of id and depth.

}  // namespace voxvis::render::detail

namespace voxvis::render {

struct Renderer::Impl {
  std::unique_ptr<detail::EglContext> egl;
  ContextInfo info;
  GLuint program = 0, vao = 0, corner_vbo = 0, index_ebo = 0, instance_vbo = 0;
  GLuint fbo = 0, id_tex = 0, depth_rb = 0;  // The id image is a texture: the id set's pass reads it.
  GLint u_right = -1, u_up = -1, u_f = -1, u_tan = -1, u_size = -1, u_range = -1;
  int width = 0, height = 0;
  std::size_t instance_capacity = 0;
  std::vector<GLuint> queries;
  std::vector<detail::Instance> instances;
  std::vector<ObjectId> drawn_ids;  // Instance number -> id.
  // The mesh pass (mesh_pass.cpp).
  GLuint mesh_program = 0, mesh_instance_vbo = 0;
  GLint mu_right = -1, mu_up = -1, mu_f = -1, mu_tan = -1, mu_range = -1;
  std::size_t mesh_instance_capacity = 0;
  std::unordered_map<const Mesh*, detail::GpuMesh> gpu_meshes;  // By the mesh's address, while it lives.
  /// This frame's mesh objects in the order added: their instance numbers,
  /// meshes and instances; upload() groups them by mesh into mesh_instances.
  std::vector<std::size_t> added_instance;
  std::vector<const detail::GpuMesh*> added_mesh;
  std::vector<detail::MeshInstance> added;
  std::vector<detail::MeshInstance> mesh_instances;  // Uploaded, grouped by mesh.
  std::vector<const detail::GpuMesh*> slot_mesh;     // Per mesh instance: its mesh.
  std::vector<std::uint32_t> mesh_slot;              // Per instance of a mesh: its mesh instance.
  std::vector<detail::MeshGroup> mesh_groups;
  std::vector<ObjectId> ids;        // Last id image, once read (read_id_image).
  std::vector<std::uint32_t> raw;         // The image as read: instance numbers.
  std::vector<std::uint32_t> seen_flags;  // Per instance number: seen at a pixel centre.
  // The id set gathered on the GPU (readback.cpp); no program: OpenGL 4.2,
  // the image is read instead.
  GLuint seen_program = 0, seen_buffer = 0;
  GLint su_size = -1;
  std::size_t seen_capacity = 0;
  // Query results read a round at once (readback.cpp); 0: below OpenGL 4.4,
  // or ContextOptions::batch_queries off.
  GLuint query_buffer = 0;
  std::size_t query_buffer_capacity = 0;
  /// The last Method::Ids call's image, not read yet: last_ids() reads it
  /// (of ids_w x ids_h), until the renderer draws again.
  bool ids_pending = false;
  int ids_w = 0, ids_h = 0;
  detail::RefineState refine;      // The refinement levels' state between frames.

  ~Impl() {
    if (!egl) return;
    std::string ignored;
    if (egl->make_current(&ignored)) {
      if (!queries.empty()) glDeleteQueries(static_cast<GLsizei>(queries.size()), queries.data());
      glDeleteFramebuffers(1, &fbo);
      glDeleteTextures(1, &id_tex);
      glDeleteRenderbuffers(1, &depth_rb);
      glDeleteBuffers(1, &seen_buffer);
      glDeleteBuffers(1, &query_buffer);
      glDeleteProgram(seen_program);
      glDeleteBuffers(1, &corner_vbo);
      glDeleteBuffers(1, &index_ebo);
      glDeleteBuffers(1, &instance_vbo);
      glDeleteVertexArrays(1, &vao);
      glDeleteProgram(program);
      release_meshes();
    }
  }

  bool setup(const ContextOptions& options, std::string* error);
  // What comes back from the GPU (readback.cpp).
  bool setup_id_set(IdReadback readback, std::string* error);
  void setup_query_buffer(bool wanted);
  /// The results of queries[0, count), waiting for them: one read of the
  /// query buffer, else one glGetQueryObjectuiv each.
  void read_queries(std::size_t count, std::vector<GLuint>* out);
  /// seen[k] != 0 for every instance number k (1..n) the w x h id image holds.
  bool gather_seen(std::size_t n, int w, int h, std::vector<std::uint32_t>* seen, std::string* error);
  /// Reads the pending id image into `ids`.
  bool read_id_image(std::string* error);
  bool resize(int w, int h, std::string* error);
  /// Forgets this frame's instances (objects, meshes, query boxes).
  void clear_instances();
  /// Adds object `o` as an instance numbered `index` when it may meet the
  /// frustum (false, nothing added, when it cannot, or is a mesh object
  /// without triangles); its world box [lo, hi] (a mesh's: object_bounds,
  /// the box of its placed vertices) goes to `lo`, `hi` when given.
  bool add_object(const detail::Basis& b, const ObjectDesc& o, std::uint32_t index, glm::dvec3* lo = nullptr,
                  glm::dvec3* hi = nullptr);
  /// Draws instance k alone (a ball or box; a mesh's triangles), in the
  /// current depth and colour state.
  void draw_instance(std::size_t k);
  /// Checks the resolution and camera, makes the context current and sizes
  /// the framebuffer.
  bool begin(const Camera& cam, int w, int h, detail::Basis* b, std::string* error);
  /// An instance of a ball or box relative to the eye, numbered `index`.
  static detail::Instance instance(const detail::Basis& b, const Vec3& centre, const Vec3& half, bool box,
                                   std::uint32_t index);
  /// Uploads `instances` and the mesh instances, grouped by mesh.
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
  // The mesh pass (mesh_pass.cpp).
  bool setup_meshes(std::string* error);
  void release_meshes();
  /// The mesh's buffers, made on first use; forgets those of meshes gone.
  const detail::GpuMesh& gpu_mesh(const std::shared_ptr<const Mesh>& mesh);
  /// Adds mesh object `o` (with triangles), its world box [lo, hi].
  void add_mesh(const detail::Basis& b, const ObjectDesc& o, std::uint32_t index, const glm::dvec3& lo,
                const glm::dvec3& hi);
  void upload_meshes();
  /// The camera's uniforms of the mesh program.
  void mesh_uniforms(const detail::Basis& b);
  /// Draws the mesh instances of instance number below `n` (depth pass).
  void draw_meshes(std::size_t n);
  /// Draws mesh instance `slot` alone.
  void draw_mesh(std::uint32_t slot);
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
