// readback.cpp — what comes back from the GPU, in as few round trips and
// bytes as a frame allows.
//
// The id set: the objects seen at the id image's pixel centres, gathered on
// the GPU: a compute pass marks each instance number found in
// the image in a buffer of flags, and only the flags come back (4 bytes an
// object in the frustum, where the image is 4 bytes a pixel: 0.9 MB at
// 640x360, 8 MB at 1920x1080, which a GPU read back five times slower than
// it drew it). The image itself is read only when asked for
// (Renderer::last_ids: confirming a miss needs its pixels). A context below
// OpenGL 4.3 (no compute shaders), or by default a software renderer (whose
// image a copy reads about as fast as a shader pass), reads the image instead.
//
// Query results: a round's queries write their results into a query buffer
// object on the GPU (OpenGL 4.4) and one read brings them all back, as
// CHC++'s multiqueries do, where one glGetQueryObjectuiv each costs a round
// trip (about 30 us on an NVIDIA H200: 336 queries, 10.6 ms).
#include <algorithm>
#include <cstdint>
#include <string>
#include <vector>

#include "renderer_impl.h"

namespace voxvis::render {
namespace {

constexpr const char* kSeenShader = R"(#version 430 core
layout(local_size_x = 16, local_size_y = 16) in;
layout(r32ui, binding = 0) readonly uniform uimage2D u_ids;
layout(std430, binding = 0) buffer Seen { uint seen[]; };
uniform ivec2 u_size;
void main() {
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  if (p.x >= u_size.x || p.y >= u_size.y) return;
  uint k = imageLoad(u_ids, p).r;
  if (k != 0u && k < uint(seen.length())) seen[k] = 1u;  // read_id_image names a stray number.
}
)";


}  // namespace

bool Renderer::Impl::setup_id_set(IdReadback readback, std::string* error) {
  GLint major = 0, minor = 0;
  glGetIntegerv(GL_MAJOR_VERSION, &major);
  glGetIntegerv(GL_MINOR_VERSION, &minor);
  if (major < 4 || (major == 4 && minor < 3)) return true;  // No compute shaders: read the image.
  const bool software = info.software || info.gl_renderer.find("llvmpipe") != std::string::npos ||
                        info.gl_renderer.find("softpipe") != std::string::npos;
  if (readback == IdReadback::Image || (readback == IdReadback::Auto && software)) return true;
  seen_program = detail::link_stages({{GL_COMPUTE_SHADER, kSeenShader}}, error);
  if (seen_program == 0) return false;
  su_size = glGetUniformLocation(seen_program, "u_size");
  glGenBuffers(1, &seen_buffer);
  info.id_set_on_gpu = true;
  return gl_ok("the id set's set-up", error);
}

bool Renderer::Impl::gather_seen(std::size_t n, int w, int h, std::vector<std::uint32_t>* seen, std::string* error) {
  const std::size_t count = n + 1;  // Instance numbers 1..n; 0 is no object.
  const auto bytes = static_cast<GLsizeiptr>(count * sizeof(std::uint32_t));
  glBindBuffer(GL_SHADER_STORAGE_BUFFER, seen_buffer);
  if (seen_capacity < count) {
    glBufferData(GL_SHADER_STORAGE_BUFFER, bytes, nullptr, GL_DYNAMIC_READ);
    seen_capacity = count;
  }
  const GLuint zero = 0;
  glClearBufferSubData(GL_SHADER_STORAGE_BUFFER, GL_R32UI, 0, bytes, GL_RED_INTEGER, GL_UNSIGNED_INT, &zero);
  glUseProgram(seen_program);
  glUniform2i(su_size, w, h);
  glBindImageTexture(0, id_tex, 0, GL_FALSE, 0, GL_READ_ONLY, GL_R32UI);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, seen_buffer);
  glDispatchCompute(static_cast<GLuint>((w + 15) / 16), static_cast<GLuint>((h + 15) / 16), 1);
  glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
  seen->resize(count);
  glGetBufferSubData(GL_SHADER_STORAGE_BUFFER, 0, bytes, seen->data());
  glUseProgram(program);
  return gl_ok("gathering the ids seen", error);
}

void Renderer::Impl::setup_query_buffer(bool wanted) {
  GLint major = 0, minor = 0;
  glGetIntegerv(GL_MAJOR_VERSION, &major);
  glGetIntegerv(GL_MINOR_VERSION, &minor);
  if (!wanted || major < 4 || (major == 4 && minor < 4)) return;  // One read per query.
  glGenBuffers(1, &query_buffer);
  info.query_buffer = true;
}

void Renderer::Impl::read_queries(std::size_t count, std::vector<GLuint>* out) {
  out->assign(count, 0);
  if (count == 0) return;
  if (query_buffer == 0) {
    for (std::size_t q = 0; q < count; ++q) glGetQueryObjectuiv(queries[q], GL_QUERY_RESULT, &(*out)[q]);
    return;
  }
  const auto bytes = static_cast<GLsizeiptr>(count * sizeof(GLuint));
  glBindBuffer(GL_QUERY_BUFFER, query_buffer);
  if (query_buffer_capacity < count) {
    glBufferData(GL_QUERY_BUFFER, bytes, nullptr, GL_STREAM_READ);
    query_buffer_capacity = count;
  }
  // With a query buffer bound the last argument is an offset into it: the
  // GPU writes each result when it has it, and nothing waits here.
  for (std::size_t q = 0; q < count; ++q)
    glGetQueryObjectuiv(queries[q], GL_QUERY_RESULT,
                        reinterpret_cast<GLuint*>(static_cast<std::uintptr_t>(q * sizeof(GLuint))));
  glGetBufferSubData(GL_QUERY_BUFFER, 0, bytes, out->data());
  // Unbound, so that the next glGetQueryObjectuiv writes to memory again.
  glBindBuffer(GL_QUERY_BUFFER, 0);
}

bool Renderer::Impl::read_id_image(std::string* error) {
  raw.resize(static_cast<std::size_t>(ids_w) * static_cast<std::size_t>(ids_h));
  glBindFramebuffer(GL_FRAMEBUFFER, fbo);
  glPixelStorei(GL_PACK_ALIGNMENT, 4);
  glReadBuffer(GL_COLOR_ATTACHMENT0);
  glReadPixels(0, 0, ids_w, ids_h, GL_RED_INTEGER, GL_UNSIGNED_INT, raw.data());
  if (!gl_ok("reading the id buffer", error)) return false;
  ids.resize(raw.size());
  for (std::size_t i = 0; i < raw.size(); ++i) {
    const std::uint32_t k = raw[i];
    if (k > drawn_ids.size()) {
      *error = "the id buffer holds an instance number that was never drawn";
      return false;
    }
    ids[i] = k == 0 ? 0 : drawn_ids[k - 1];
  }
  ids_pending = false;
  return true;
}

}  // namespace voxvis::render
