// renderer.cpp — Renderer: the exact-object pass (shaders.h; meshes in
// mesh_pass.cpp) into an id and depth framebuffer, read back once
// (Method::Ids) or probed with one occlusion query per candidate
// (Method::Queries).
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

#include "renderer_impl.h"
#include "shaders.h"
#include "voxvis/mesh.h"
#include "voxvis/render.h"

namespace voxvis::render {

using detail::Basis;
using detail::Clock;
using detail::Instance;
using detail::kFlushEvery;
using detail::kMaxPixels;
using detail::ms_since;

namespace {

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
constexpr std::uint8_t kTriangles[detail::kBoxIndices] = {
    0, 2, 1, 1, 2, 3,  // z = -1
    4, 5, 6, 5, 7, 6,  // z = +1
    0, 1, 4, 1, 5, 4,  // y = -1
    2, 6, 3, 3, 6, 7,  // y = +1
    0, 4, 2, 2, 4, 6,  // x = -1
    1, 3, 5, 3, 7, 5,  // x = +1
};

}  // namespace

GLuint detail::link_program(const char* vertex, const char* fragment, std::string* error) {
  return link_stages({{GL_VERTEX_SHADER, vertex}, {GL_FRAGMENT_SHADER, fragment}}, error);
}

GLuint detail::link_stages(std::initializer_list<std::pair<GLenum, const char*>> stages, std::string* error) {
  std::vector<GLuint> shaders;
  for (const auto& [type, source] : stages) {
    const GLuint s = compile(type, source, error);
    if (s == 0) {
      for (GLuint done : shaders) glDeleteShader(done);
      return 0;
    }
    shaders.push_back(s);
  }
  const GLuint program = glCreateProgram();
  for (GLuint s : shaders) glAttachShader(program, s);
  glLinkProgram(program);
  for (GLuint s : shaders) glDeleteShader(s);
  GLint ok = 0;
  glGetProgramiv(program, GL_LINK_STATUS, &ok);
  if (!ok) {
    *error = "shader link failed: " + info_log(program, true);
    glDeleteProgram(program);
    return 0;
  }
  return program;
}

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

bool parse_id_readback(const std::string& text, IdReadback* out, std::string* message) {
  if (text == "auto") *out = IdReadback::Auto;
  else if (text == "set") *out = IdReadback::Set;
  else if (text == "image") *out = IdReadback::Image;
  else {
    *message = "unknown id read-back '" + text + "' (known: auto, set, image)";
    return false;
  }
  return true;
}

const char* id_readback_name(IdReadback r) {
  switch (r) {
    case IdReadback::Auto: return "auto";
    case IdReadback::Set: return "set";
    case IdReadback::Image: return "image";
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

bool parse_resolution(const std::string& text, int* w, int* h, std::string* message) {
  const std::size_t x = text.find('x');
  auto number = [](const std::string& s, int* v) {
    if (s.empty() || s.size() > 9 || s.find_first_not_of("0123456789") != std::string::npos) return false;
    *v = std::stoi(s);
    return true;
  };
  if (x == std::string::npos || !number(text.substr(0, x), w) || !number(text.substr(x + 1), h)) {
    *message = "expected WIDTHxHEIGHT in pixels (for example 640x360), got '" + text + "'";
    return false;
  }
  if (*w < 1 || *h < 1) {
    *message = "width and height must be >= 1, got '" + text + "'";
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
  if (!why.empty()) s += " (" + why + ")";
  s += id_set_on_gpu ? "; ids read back as a set" : "; ids read back as an image";
  s += query_buffer ? ", query results a round at once" : ", query results one by one";
  return s;
}

bool Renderer::Impl::setup(const ContextOptions& options, std::string* error) {
  GLint max_rb = 0, dims[2] = {0, 0};
  glGetIntegerv(GL_MAX_RENDERBUFFER_SIZE, &max_rb);
  glGetIntegerv(GL_MAX_VIEWPORT_DIMS, dims);
  info.max_size = std::min({max_rb, dims[0], dims[1]});

  program = detail::link_program(detail::kVertexShader, detail::kFragmentShader, error);
  if (program == 0) return false;
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
  if (!setup_meshes(error)) return false;
  if (!setup_id_set(options.id_readback, error)) return false;
  setup_query_buffer(options.batch_queries);
  glUseProgram(program);
  glBindVertexArray(vao);
  return gl_ok("set-up", error);
}

bool Renderer::Impl::resize(int w, int h, std::string* error) {
  if (w == width && h == height) return true;
  // An immutable texture: made again at each new size.
  if (id_tex != 0) glDeleteTextures(1, &id_tex);
  glGenTextures(1, &id_tex);
  glBindTexture(GL_TEXTURE_2D, id_tex);
  glTexStorage2D(GL_TEXTURE_2D, 1, GL_R32UI, w, h);
  glBindRenderbuffer(GL_RENDERBUFFER, depth_rb);
  glRenderbufferStorage(GL_RENDERBUFFER, GL_DEPTH_COMPONENT32F, w, h);
  glBindFramebuffer(GL_FRAMEBUFFER, fbo);
  glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, id_tex, 0);
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
  if (!impl->setup(options, error)) return nullptr;
  return std::unique_ptr<Renderer>(new Renderer(std::move(impl)));
}

const ContextInfo& Renderer::info() const { return impl_->info; }
const std::vector<ObjectId>& Renderer::last_ids() const {
  Impl& m = *impl_;
  if (m.ids_pending) {
    std::string error;
    if (!m.egl->make_current(&error) || !m.read_id_image(&error)) {
      m.ids.clear();
      m.ids_pending = false;
    }
  }
  return m.ids;
}

bool Renderer::Impl::begin(const Camera& cam, int w, int h, Basis* b, std::string* error) {
  if (w < 1 || h < 1 || w > info.max_size || h > info.max_size || std::int64_t{w} * h > kMaxPixels) {
    *error = "resolution " + std::to_string(w) + "x" + std::to_string(h) + " is out of range (each side 1 to " +
             std::to_string(info.max_size) + " pixels, at most " + std::to_string(kMaxPixels) + " pixels in all)";
    return false;
  }
  if (!make_basis(cam, b, error)) return false;
  if (!egl->make_current(error)) return false;
  return resize(w, h, error);
}

Instance Renderer::Impl::instance(const Basis& b, const Vec3& centre, const Vec3& half, bool box,
                                  std::uint32_t index) {
  // Relative to the eye in double before rounding to float.
  Instance in{};
  const glm::dvec3 c = centre - b.eye;
  for (int a = 0; a < 3; ++a) {
    in.centre[a] = static_cast<float>(c[a]);
    in.half[a] = static_cast<float>(half[a]);
  }
  in.kind = box ? detail::kBox : detail::kBall;
  in.index = index;
  return in;
}

void Renderer::Impl::clear_instances() {
  instances.clear();
  added_instance.clear();
  added_mesh.clear();
  added.clear();
  mesh_slot.clear();
  mesh_groups.clear();
}

bool Renderer::Impl::add_object(const Basis& b, const ObjectDesc& o, std::uint32_t index, glm::dvec3* lo,
                                glm::dvec3* hi) {
  glm::dvec3 l, h;
  if (o.shape == Shape::Mesh) {
    if (!o.mesh || o.mesh->triangles.empty()) return false;
    object_bounds(o, &l, &h);
    const glm::dvec3 c = 0.5 * (l + h);
    if (!detail::may_meet_frustum(b, c, h - c, false)) return false;
    add_mesh(b, o, index, l, h);
  } else {
    if (!detail::may_meet_frustum(b, o)) return false;
    const Vec3 half = o.shape == Shape::Sphere ? Vec3(o.radius) : o.half_extent;
    instances.push_back(instance(b, o.center, half, o.shape == Shape::Box, index));
    l = o.center - half;
    h = o.center + half;
  }
  if (lo) *lo = l;
  if (hi) *hi = h;
  return true;
}

void Renderer::Impl::draw_instance(std::size_t k) {
  if (instances[k].kind > 1.5f) return draw_mesh(mesh_slot[k]);
  glDrawElementsInstancedBaseInstance(GL_TRIANGLES, detail::kBoxIndices, GL_UNSIGNED_BYTE, nullptr, 1,
                                      static_cast<GLuint>(k));
}

void Renderer::Impl::upload() {
  upload_meshes();
  glBindBuffer(GL_ARRAY_BUFFER, instance_vbo);
  if (instances.size() > instance_capacity) {
    instance_capacity = std::max(instances.size(), 2 * instance_capacity);
    glBufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(instance_capacity * sizeof(Instance)), nullptr,
                 GL_STREAM_DRAW);
  }
  if (!instances.empty())
    glBufferSubData(GL_ARRAY_BUFFER, 0, static_cast<GLsizeiptr>(instances.size() * sizeof(Instance)),
                    instances.data());
}

void Renderer::Impl::depth_pass(const Basis& b, int w, int h, std::ptrdiff_t count) {
  // The last id image is overwritten: last_ids() holds none until the next
  // Method::Ids call.
  ids_pending = false;
  ids.clear();
  glBindFramebuffer(GL_FRAMEBUFFER, fbo);
  glViewport(0, 0, w, h);
  glUseProgram(program);
  glBindVertexArray(vao);
  glUniform3f(u_right, static_cast<float>(b.right.x), static_cast<float>(b.right.y), static_cast<float>(b.right.z));
  glUniform3f(u_up, static_cast<float>(b.up.x), static_cast<float>(b.up.y), static_cast<float>(b.up.z));
  glUniform3f(u_f, static_cast<float>(b.f.x), static_cast<float>(b.f.y), static_cast<float>(b.f.z));
  glUniform2f(u_tan, static_cast<float>(b.tanx), static_cast<float>(b.tany));
  glUniform2f(u_size, static_cast<float>(w), static_cast<float>(h));
  glUniform2f(u_range, static_cast<float>(b.near), static_cast<float>(b.far));
  mesh_uniforms(b);
  const GLuint zero[4] = {0, 0, 0, 0};
  glClearBufferuiv(GL_COLOR, 0, zero);
  const GLfloat far_depth = 1.0f;
  glClearBufferfv(GL_DEPTH, 0, &far_depth);
  glDepthMask(GL_TRUE);
  glColorMaski(0, GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
  glDepthFunc(GL_LESS);
  const auto n = static_cast<GLsizei>(count < 0 ? static_cast<std::ptrdiff_t>(instances.size()) : count);
  if (n > 0) glDrawElementsInstanced(GL_TRIANGLES, detail::kBoxIndices, GL_UNSIGNED_BYTE, nullptr, n);
  draw_meshes(static_cast<std::size_t>(n));
}

void Renderer::Impl::begin_probes(std::size_t n) {
  if (queries.size() < n) {
    const std::size_t old = queries.size();
    queries.resize(n);
    glGenQueries(static_cast<GLsizei>(n - old), queries.data() + old);
  }
  glDepthMask(GL_FALSE);
  glColorMaski(0, GL_FALSE, GL_FALSE, GL_FALSE, GL_FALSE);
  glDepthFunc(GL_LEQUAL);
}

void Renderer::Impl::probe(GLenum target, std::size_t q, std::size_t k) {
  glBeginQuery(target, queries[q]);
  draw_instance(k);
  glEndQuery(target);
  if ((q + 1) % kFlushEvery == 0) glFlush();
}

void Renderer::Impl::end_probes() {
  glDepthMask(GL_TRUE);
  glColorMaski(0, GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
  glDepthFunc(GL_LESS);
}

bool Renderer::visible(const std::vector<ObjectDesc>& objects, const Camera& cam, const VisibleOptions& options,
                       const std::vector<ObjectId>* candidates, std::vector<ObjectId>* out,
                       VisibleStats* stats, std::string* error) {
  Impl& m = *impl_;
  *stats = VisibleStats{};
  out->clear();
  const int w = options.width, h = options.height;
  Basis b;
  if (!m.begin(cam, w, h, &b, error)) return false;

  // Instances: the objects the frustum may hold, in the order given.
  auto t0 = Clock::now();
  m.clear_instances();
  m.drawn_ids.clear();
  for (const ObjectDesc& o : objects)
    if (m.add_object(b, o, static_cast<std::uint32_t>(m.drawn_ids.size() + 1))) m.drawn_ids.push_back(o.id);
  const auto n = static_cast<GLsizei>(m.instances.size());
  stats->in_frustum = static_cast<std::uint32_t>(n);
  m.upload();
  stats->upload_ms = ms_since(t0);

  // The depth and id pass.
  t0 = Clock::now();
  m.depth_pass(b, w, h);
  glFinish();
  stats->draw_ms = ms_since(t0);
  if (!m.gl_ok("the depth and id pass", error)) return false;

  auto wanted = [&](ObjectId id) {
    return candidates == nullptr || std::binary_search(candidates->begin(), candidates->end(), id);
  };

  if (options.method == Method::Ids) {
    t0 = Clock::now();
    m.ids_w = w;
    m.ids_h = h;
    m.ids_pending = true;
    std::vector<std::uint32_t>& seen = m.seen_flags;
    if (m.seen_program != 0) {
      // The set gathered on the GPU; the image read only if asked for.
      if (!m.gather_seen(m.drawn_ids.size(), w, h, &seen, error)) return false;
    } else {
      if (!m.read_id_image(error)) return false;
      seen.assign(m.drawn_ids.size() + 1, 0);
      for (const std::uint32_t k : m.raw) seen[k] = 1;
    }
    for (std::size_t k = 1; k < seen.size(); ++k)
      if (seen[k] != 0 && wanted(m.drawn_ids[k - 1])) out->push_back(m.drawn_ids[k - 1]);
    stats->read_ms = ms_since(t0);
  } else {
    // One query per candidate in the frustum, drawn against the finished
    // depth buffer; all issued before any is read. GL_SAMPLES_PASSED, as the
    // refinement levels: a query object keeps the kind it was first begun
    // with, and they share the pool.
    t0 = Clock::now();
    std::vector<GLsizei> probe;
    for (GLsizei k = 0; k < n; ++k)
      if (wanted(m.drawn_ids[static_cast<std::size_t>(k)])) probe.push_back(k);
    m.begin_probes(probe.size());
    for (std::size_t q = 0; q < probe.size(); ++q)
      m.probe(GL_SAMPLES_PASSED, q, static_cast<std::size_t>(probe[q]));
    glFlush();
    stats->queries = static_cast<std::uint32_t>(probe.size());
    stats->query_ms = ms_since(t0);
    t0 = Clock::now();
    std::vector<GLuint> passed;
    m.read_queries(probe.size(), &passed);
    for (std::size_t q = 0; q < probe.size(); ++q)
      if (passed[q]) out->push_back(m.drawn_ids[static_cast<std::size_t>(probe[q])]);
    stats->read_ms = ms_since(t0);
    m.end_probes();
    if (!m.gl_ok("the occlusion queries", error)) return false;
  }
  std::sort(out->begin(), out->end());
  out->erase(std::unique(out->begin(), out->end()), out->end());
  return true;
}

}  // namespace voxvis::render
