// renderer.cpp — Renderer: the exact-object pass (shaders.h) into an id and
// depth framebuffer, read back once (Method::Ids) or probed with one
// occlusion query per candidate (Method::Queries).
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#define GL_GLEXT_PROTOTYPES 1
#include <GL/glcorearb.h>

#include "egl_context.h"
#include "shaders.h"
#include "voxvis/render.h"

namespace voxvis::render {

namespace {

using Clock = std::chrono::steady_clock;
double ms_since(Clock::time_point t0) {
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
/// ray caster builds it (tests/support/raycast.h).
struct Basis {
  glm::dvec3 eye, f, right, up;
  double tanx = 1.0, tany = 1.0, near = 0.05, far = 1000.0;
};

bool make_basis(const Camera& cam, Basis* b, std::string* error) {
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
bool may_meet_frustum(const Basis& b, const ObjectDesc& o) {
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

/// The compiler's or linker's log of a shader or program.
std::string info_log(GLuint object, bool program) {
  char log[2048] = {};
  if (program)
    glGetProgramInfoLog(object, sizeof log, nullptr, log);
  else
    glGetShaderInfoLog(object, sizeof log, nullptr, log);
  return log;
}

GLuint compile(GLenum type, const char* source, std::string* error) {
  const GLuint s = glCreateShader(type);
  glShaderSource(s, 1, &source, nullptr);
  glCompileShader(s);
  GLint ok = 0;
  glGetShaderiv(s, GL_COMPILE_STATUS, &ok);
  if (!ok) {
    *error = "shader compilation failed: " + info_log(s, false);
    glDeleteShader(s);
    return 0;
  }
  return s;
}

// The cube [-1, 1]^3: corners, and its twelve triangles wound counter-
// clockwise seen from outside.
constexpr float kCorners[8][3] = {{-1, -1, -1}, {1, -1, -1}, {-1, 1, -1}, {1, 1, -1},
                                  {-1, -1, 1},  {1, -1, 1},  {-1, 1, 1},  {1, 1, 1}};
constexpr std::uint8_t kTriangles[36] = {
    0, 2, 1, 1, 2, 3,  // z = -1
    4, 5, 6, 5, 7, 6,  // z = +1
    0, 1, 4, 1, 5, 4,  // y = -1
    2, 6, 3, 3, 6, 7,  // y = +1
    0, 4, 2, 2, 4, 6,  // x = -1
    1, 3, 5, 3, 7, 5,  // x = +1
};

constexpr int kFlushEvery = 512;       // Queries between flushes (long unflushed batches misreport on llvmpipe).
constexpr std::int64_t kMaxPixels = std::int64_t{1} << 26;  // 64 Mpixel: 512 MiB of id and depth.

}  // namespace

bool parse_platform(const std::string& text, Platform* out, std::string* message) {
  if (text == "auto") *out = Platform::Auto;
  else if (text == "device") *out = Platform::Device;
  else if (text == "surfaceless") *out = Platform::Surfaceless;
  else {
    *message = "unknown EGL platform '" + text + "' (known: auto, device, surfaceless)";
    return false;
  }
  return true;
}

const char* platform_name(Platform p) {
  switch (p) {
    case Platform::Auto: return "auto";
    case Platform::Device: return "device";
    case Platform::Surfaceless: return "surfaceless";
  }
  return "?";
}

bool parse_method(const std::string& text, Method* out, std::string* message) {
  if (text == "ids") *out = Method::Ids;
  else if (text == "queries") *out = Method::Queries;
  else {
    *message = "unknown method '" + text + "' (known: ids, queries)";
    return false;
  }
  return true;
}

const char* method_name(Method m) { return m == Method::Ids ? "ids" : "queries"; }

std::string ContextInfo::summary() const {
  std::string s = "EGL ";
  s += platform_name(platform);
  if (platform == Platform::Device) {
    s += " ";
    s += std::to_string(device);
    s += " of ";
    s += std::to_string(devices);
    if (software) s += " (software)";
  }
  s += ", ";
  s += gl_renderer;
  s += ", OpenGL ";
  s += gl_version;
  return s;
}

struct Renderer::Impl {
  std::unique_ptr<detail::EglContext> egl;
  ContextInfo info;
  GLuint program = 0, vao = 0, corner_vbo = 0, index_ebo = 0, instance_vbo = 0;
  GLuint fbo = 0, id_rb = 0, depth_rb = 0;
  GLint u_right = -1, u_up = -1, u_f = -1, u_tan = -1, u_size = -1, u_range = -1;
  int width = 0, height = 0;
  std::size_t instance_capacity = 0;
  std::vector<GLuint> queries;
  std::vector<Instance> instances;
  std::vector<ObjectId> drawn_ids;  // Instance number -> id.
  std::vector<ObjectId> ids;        // Last id image.
  std::vector<std::uint32_t> raw;

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
  bool gl_ok(const char* what, std::string* error) {
    const GLenum e = glGetError();
    if (e == GL_NO_ERROR) return true;
    char code[16];
    std::snprintf(code, sizeof code, "0x%04x", e);
    *error = std::string("OpenGL error ") + code + " in " + what;
    return false;
  }
};

bool Renderer::Impl::setup(std::string* error) {
  GLint max_rb = 0, dims[2] = {0, 0};
  glGetIntegerv(GL_MAX_RENDERBUFFER_SIZE, &max_rb);
  glGetIntegerv(GL_MAX_VIEWPORT_DIMS, dims);
  info.max_size = std::min({max_rb, dims[0], dims[1]});

  const GLuint vs = compile(GL_VERTEX_SHADER, detail::kVertexShader, error);
  if (vs == 0) return false;
  const GLuint fs = compile(GL_FRAGMENT_SHADER, detail::kFragmentShader, error);
  if (fs == 0) {
    glDeleteShader(vs);
    return false;
  }
  program = glCreateProgram();
  glAttachShader(program, vs);
  glAttachShader(program, fs);
  glLinkProgram(program);
  glDeleteShader(vs);
  glDeleteShader(fs);
  GLint ok = 0;
  glGetProgramiv(program, GL_LINK_STATUS, &ok);
  if (!ok) {
    *error = "shader link failed: " + info_log(program, true);
    return false;
  }
  u_right = glGetUniformLocation(program, "u_right");
  u_up = glGetUniformLocation(program, "u_up");
  u_f = glGetUniformLocation(program, "u_f");
  u_tan = glGetUniformLocation(program, "u_tan");
  u_size = glGetUniformLocation(program, "u_size");
  u_range = glGetUniformLocation(program, "u_range");

  glGenVertexArrays(1, &vao);
  glBindVertexArray(vao);
  glGenBuffers(1, &corner_vbo);
  glBindBuffer(GL_ARRAY_BUFFER, corner_vbo);
  glBufferData(GL_ARRAY_BUFFER, sizeof kCorners, kCorners, GL_STATIC_DRAW);
  glEnableVertexAttribArray(0);
  glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 3 * sizeof(float), nullptr);
  glGenBuffers(1, &index_ebo);
  glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, index_ebo);
  glBufferData(GL_ELEMENT_ARRAY_BUFFER, sizeof kTriangles, kTriangles, GL_STATIC_DRAW);
  glGenBuffers(1, &instance_vbo);
  glBindBuffer(GL_ARRAY_BUFFER, instance_vbo);
  const auto stride = static_cast<GLsizei>(sizeof(Instance));
  glEnableVertexAttribArray(1);
  glVertexAttribPointer(1, 4, GL_FLOAT, GL_FALSE, stride, reinterpret_cast<const void*>(offsetof(Instance, centre)));
  glVertexAttribDivisor(1, 1);
  glEnableVertexAttribArray(2);
  glVertexAttribPointer(2, 3, GL_FLOAT, GL_FALSE, stride, reinterpret_cast<const void*>(offsetof(Instance, half)));
  glVertexAttribDivisor(2, 1);
  glEnableVertexAttribArray(3);
  glVertexAttribIPointer(3, 1, GL_UNSIGNED_INT, stride, reinterpret_cast<const void*>(offsetof(Instance, index)));
  glVertexAttribDivisor(3, 1);

  glGenFramebuffers(1, &fbo);
  glGenRenderbuffers(1, &id_rb);
  glGenRenderbuffers(1, &depth_rb);

  // Back faces only: each ray through an object's proxy leaves it once, so
  // every pixel gets one fragment per object, also with the eye inside.
  glEnable(GL_CULL_FACE);
  glCullFace(GL_FRONT);
  glFrontFace(GL_CCW);
  // No near or far clipping of the proxies (the fragment test clips the
  // object itself); the rays behind the eye are cut by the side planes.
  glEnable(GL_DEPTH_CLAMP);
  glEnable(GL_DEPTH_TEST);
  return gl_ok("set-up", error);
}

bool Renderer::Impl::resize(int w, int h, std::string* error) {
  if (w == width && h == height) return true;
  glBindRenderbuffer(GL_RENDERBUFFER, id_rb);
  glRenderbufferStorage(GL_RENDERBUFFER, GL_R32UI, w, h);
  glBindRenderbuffer(GL_RENDERBUFFER, depth_rb);
  glRenderbufferStorage(GL_RENDERBUFFER, GL_DEPTH_COMPONENT32F, w, h);
  glBindFramebuffer(GL_FRAMEBUFFER, fbo);
  glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, id_rb);
  glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, depth_rb);
  const GLenum status = glCheckFramebufferStatus(GL_FRAMEBUFFER);
  if (status != GL_FRAMEBUFFER_COMPLETE) {
    *error = "framebuffer of " + std::to_string(w) + "x" + std::to_string(h) + " is incomplete";
    width = height = 0;
    return false;
  }
  if (!gl_ok("framebuffer allocation", error)) {
    width = height = 0;
    return false;
  }
  width = w;
  height = h;
  return true;
}

Renderer::Renderer(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Renderer::~Renderer() = default;

std::unique_ptr<Renderer> Renderer::create(const ContextOptions& options, std::string* error) {
  auto impl = std::make_unique<Impl>();
  impl->egl = detail::EglContext::create(options, &impl->info, error);
  if (!impl->egl) return nullptr;
  if (!impl->setup(error)) return nullptr;
  return std::unique_ptr<Renderer>(new Renderer(std::move(impl)));
}

const ContextInfo& Renderer::info() const { return impl_->info; }
const std::vector<ObjectId>& Renderer::last_ids() const { return impl_->ids; }

bool Renderer::visible(const std::vector<ObjectDesc>& objects, const Camera& cam, const VisibleOptions& options,
                       const std::vector<ObjectId>* candidates, std::vector<ObjectId>* out,
                       VisibleStats* stats, std::string* error) {
  Impl& m = *impl_;
  *stats = VisibleStats{};
  out->clear();
  const int w = options.width, h = options.height;
  if (w < 1 || h < 1 || w > m.info.max_size || h > m.info.max_size ||
      std::int64_t{w} * h > kMaxPixels) {
    *error = "resolution " + std::to_string(w) + "x" + std::to_string(h) + " is out of range (each side 1 to " +
             std::to_string(m.info.max_size) + " pixels, at most " + std::to_string(kMaxPixels) +
             " pixels in all)";
    return false;
  }
  Basis b;
  if (!make_basis(cam, &b, error)) return false;
  if (!m.egl->make_current(error)) return false;
  if (!m.resize(w, h, error)) return false;

  // Instances: the objects the frustum may hold, relative to the eye in
  // double before rounding to float, in the order given.
  auto t0 = Clock::now();
  m.instances.clear();
  m.drawn_ids.clear();
  for (const ObjectDesc& o : objects) {
    if (!may_meet_frustum(b, o)) continue;
    Instance in{};
    const glm::dvec3 c = o.center - b.eye;
    const glm::dvec3 hx = o.shape == Shape::Sphere ? glm::dvec3(o.radius) : o.half_extent;
    for (int a = 0; a < 3; ++a) {
      in.centre[a] = static_cast<float>(c[a]);
      in.half[a] = static_cast<float>(hx[a]);
    }
    in.kind = o.shape == Shape::Sphere ? 0.0f : 1.0f;
    m.drawn_ids.push_back(o.id);
    in.index = static_cast<std::uint32_t>(m.drawn_ids.size());
    m.instances.push_back(in);
  }
  const auto n = static_cast<GLsizei>(m.instances.size());
  stats->in_frustum = static_cast<std::uint32_t>(n);
  glBindBuffer(GL_ARRAY_BUFFER, m.instance_vbo);
  if (m.instances.size() > m.instance_capacity) {
    m.instance_capacity = std::max(m.instances.size(), 2 * m.instance_capacity);
    glBufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(m.instance_capacity * sizeof(Instance)), nullptr,
                 GL_STREAM_DRAW);
  }
  if (n > 0)
    glBufferSubData(GL_ARRAY_BUFFER, 0, static_cast<GLsizeiptr>(m.instances.size() * sizeof(Instance)),
                    m.instances.data());
  stats->upload_ms = ms_since(t0);

  // The depth and id pass.
  t0 = Clock::now();
  glBindFramebuffer(GL_FRAMEBUFFER, m.fbo);
  glViewport(0, 0, w, h);
  glUseProgram(m.program);
  glBindVertexArray(m.vao);
  glUniform3f(m.u_right, static_cast<float>(b.right.x), static_cast<float>(b.right.y), static_cast<float>(b.right.z));
  glUniform3f(m.u_up, static_cast<float>(b.up.x), static_cast<float>(b.up.y), static_cast<float>(b.up.z));
  glUniform3f(m.u_f, static_cast<float>(b.f.x), static_cast<float>(b.f.y), static_cast<float>(b.f.z));
  glUniform2f(m.u_tan, static_cast<float>(b.tanx), static_cast<float>(b.tany));
  glUniform2f(m.u_size, static_cast<float>(w), static_cast<float>(h));
  glUniform2f(m.u_range, static_cast<float>(b.near), static_cast<float>(b.far));
  const GLuint zero[4] = {0, 0, 0, 0};
  glClearBufferuiv(GL_COLOR, 0, zero);
  const GLfloat far_depth = 1.0f;
  glClearBufferfv(GL_DEPTH, 0, &far_depth);
  glDepthMask(GL_TRUE);
  glColorMaski(0, GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
  glDepthFunc(GL_LESS);
  if (n > 0) glDrawElementsInstanced(GL_TRIANGLES, 36, GL_UNSIGNED_BYTE, nullptr, n);
  glFinish();
  stats->draw_ms = ms_since(t0);
  if (!m.gl_ok("the depth and id pass", error)) return false;

  auto wanted = [&](ObjectId id) {
    return candidates == nullptr || std::binary_search(candidates->begin(), candidates->end(), id);
  };

  if (options.method == Method::Ids) {
    t0 = Clock::now();
    m.raw.resize(static_cast<std::size_t>(w) * static_cast<std::size_t>(h));
    glPixelStorei(GL_PACK_ALIGNMENT, 4);
    glReadBuffer(GL_COLOR_ATTACHMENT0);
    glReadPixels(0, 0, w, h, GL_RED_INTEGER, GL_UNSIGNED_INT, m.raw.data());
    if (!m.gl_ok("reading the id buffer", error)) return false;
    m.ids.resize(m.raw.size());
    std::vector<char> seen(m.drawn_ids.size() + 1, 0);
    for (std::size_t i = 0; i < m.raw.size(); ++i) {
      const std::uint32_t k = m.raw[i];
      if (k > m.drawn_ids.size()) {
        *error = "the id buffer holds an instance number that was never drawn";
        return false;
      }
      m.ids[i] = k == 0 ? 0 : m.drawn_ids[k - 1];
      seen[k] = 1;
    }
    for (std::size_t k = 1; k < seen.size(); ++k)
      if (seen[k] && wanted(m.drawn_ids[k - 1])) out->push_back(m.drawn_ids[k - 1]);
    stats->read_ms = ms_since(t0);
  } else {
    // One query per candidate in the frustum, drawn against the finished
    // depth buffer; all issued before any is read.
    t0 = Clock::now();
    std::vector<GLsizei> probe;
    for (GLsizei k = 0; k < n; ++k)
      if (wanted(m.drawn_ids[static_cast<std::size_t>(k)])) probe.push_back(k);
    if (m.queries.size() < probe.size()) {
      const std::size_t old = m.queries.size();
      m.queries.resize(probe.size());
      glGenQueries(static_cast<GLsizei>(probe.size() - old), m.queries.data() + old);
    }
    glDepthMask(GL_FALSE);
    glColorMaski(0, GL_FALSE, GL_FALSE, GL_FALSE, GL_FALSE);
    glDepthFunc(GL_LEQUAL);
    for (std::size_t q = 0; q < probe.size(); ++q) {
      glBeginQuery(GL_ANY_SAMPLES_PASSED, m.queries[q]);
      glDrawElementsInstancedBaseInstance(GL_TRIANGLES, 36, GL_UNSIGNED_BYTE, nullptr, 1,
                                          static_cast<GLuint>(probe[q]));
      glEndQuery(GL_ANY_SAMPLES_PASSED);
      if ((q + 1) % kFlushEvery == 0) glFlush();
    }
    glFlush();
    stats->queries = static_cast<std::uint32_t>(probe.size());
    stats->query_ms = ms_since(t0);
    t0 = Clock::now();
    for (std::size_t q = 0; q < probe.size(); ++q) {
      GLuint passed = 0;
      glGetQueryObjectuiv(m.queries[q], GL_QUERY_RESULT, &passed);
      if (passed) out->push_back(m.drawn_ids[static_cast<std::size_t>(probe[q])]);
    }
    stats->read_ms = ms_since(t0);
    glDepthMask(GL_TRUE);
    glColorMaski(0, GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
    glDepthFunc(GL_LESS);
    if (!m.gl_ok("the occlusion queries", error)) return false;
  }
  std::sort(out->begin(), out->end());
  out->erase(std::unique(out->begin(), out->end()), out->end());
  return true;
}

}  // namespace voxvis::render
