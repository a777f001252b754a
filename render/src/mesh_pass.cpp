// mesh_pass.cpp — mesh objects in the renderer: their triangles drawn as
// such (shaders.h, kMeshVertexShader), one vertex and index buffer per
// distinct mesh, kept from frame to frame while the mesh lives, and one
// instance per object with its placement (voxvis/mesh.h: world = center +
// scale * rotate(rotation, model)), taken relative to the eye in double
// before it is rounded to float, as the balls' and boxes' centres are. The
// objects of one mesh are drawn by one instanced call in the depth pass, one
// at a time in queries.
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <limits>
#include <numeric>
#include <string>
#include <vector>

#include <glm/glm.hpp>
#include <glm/gtc/quaternion.hpp>

#define GL_GLEXT_PROTOTYPES 1
#include <GL/glcorearb.h>

#include "renderer_impl.h"
#include "shaders.h"
#include "voxvis/mesh.h"

namespace voxvis::render {

using detail::Basis;
using detail::GpuMesh;
using detail::MeshInstance;

namespace {

void release(GpuMesh& g) {
  glDeleteVertexArrays(1, &g.vao);
  glDeleteBuffers(1, &g.vbo);
  glDeleteBuffers(1, &g.ebo);
  g = GpuMesh{};
}

}  // namespace

bool Renderer::Impl::setup_meshes(std::string* error) {
  mesh_program = detail::link_program(detail::kMeshVertexShader, detail::kMeshFragmentShader, error);
  if (mesh_program == 0) return false;
  mu_right = glGetUniformLocation(mesh_program, "u_right");
  mu_up = glGetUniformLocation(mesh_program, "u_up");
  mu_f = glGetUniformLocation(mesh_program, "u_f");
  mu_tan = glGetUniformLocation(mesh_program, "u_tan");
  mu_range = glGetUniformLocation(mesh_program, "u_range");
  glGenBuffers(1, &mesh_instance_vbo);
  return gl_ok("the mesh pass's set-up", error);
}

void Renderer::Impl::release_meshes() {
  for (auto& [address, g] : gpu_meshes) release(g);
  gpu_meshes.clear();
  glDeleteBuffers(1, &mesh_instance_vbo);
  glDeleteProgram(mesh_program);
}

const GpuMesh& Renderer::Impl::gpu_mesh(const std::shared_ptr<const Mesh>& mesh) {
  // An entry whose mesh still lives is this mesh (no other object can have
  // its address while it lives); the others go, with their buffers.
  if (const auto it = gpu_meshes.find(mesh.get()); it != gpu_meshes.end() && !it->second.mesh.expired())
    return it->second;
  for (auto it = gpu_meshes.begin(); it != gpu_meshes.end();) {
    if (it->second.mesh.expired()) {
      release(it->second);
      it = gpu_meshes.erase(it);
    } else {
      ++it;
    }
  }
  const Mesh& m = *mesh;
  GpuMesh g;
  g.mesh = mesh;
  glm::dvec3 lo(std::numeric_limits<double>::infinity()), hi = -lo;
  for (const auto& tri : m.triangles)
    for (std::uint32_t k : tri) {
      lo = glm::min(lo, m.vertices[k]);
      hi = glm::max(hi, m.vertices[k]);
    }
  g.centre = 0.5 * lo + 0.5 * hi;
  std::vector<float> xyz(3 * m.vertices.size());
  for (std::size_t k = 0; k < m.vertices.size(); ++k)
    for (int a = 0; a < 3; ++a) xyz[3 * k + static_cast<std::size_t>(a)] = static_cast<float>(m.vertices[k][a] - g.centre[a]);
  g.indices = static_cast<GLsizei>(3 * m.triangles.size());

  glGenVertexArrays(1, &g.vao);
  glBindVertexArray(g.vao);
  glGenBuffers(1, &g.vbo);
  glBindBuffer(GL_ARRAY_BUFFER, g.vbo);
  glBufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(xyz.size() * sizeof(float)), xyz.data(), GL_STATIC_DRAW);
  glEnableVertexAttribArray(0);
  glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 3 * sizeof(float), nullptr);
  glGenBuffers(1, &g.ebo);
  glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, g.ebo);
  static_assert(sizeof(m.triangles[0]) == 3 * sizeof(GLuint));
  glBufferData(GL_ELEMENT_ARRAY_BUFFER, static_cast<GLsizeiptr>(m.triangles.size() * sizeof(m.triangles[0])),
               m.triangles.data(), GL_STATIC_DRAW);
  // The instances, one per object, from the buffer all meshes share.
  glBindBuffer(GL_ARRAY_BUFFER, mesh_instance_vbo);
  const auto stride = static_cast<GLsizei>(sizeof(MeshInstance));
  auto at = [](std::size_t offset) { return reinterpret_cast<const void*>(offset); };
  glEnableVertexAttribArray(1);
  glVertexAttribPointer(1, 3, GL_FLOAT, GL_FALSE, stride, at(offsetof(MeshInstance, offset)));
  glVertexAttribDivisor(1, 1);
  for (GLuint c = 0; c < 3; ++c) {
    glEnableVertexAttribArray(2 + c);
    glVertexAttribPointer(2 + c, 3, GL_FLOAT, GL_FALSE, stride, at(offsetof(MeshInstance, axes) + 3 * c * sizeof(float)));
    glVertexAttribDivisor(2 + c, 1);
  }
  glEnableVertexAttribArray(5);
  glVertexAttribIPointer(5, 1, GL_UNSIGNED_INT, stride, at(offsetof(MeshInstance, index)));
  glVertexAttribDivisor(5, 1);
  glBindVertexArray(vao);
  return gpu_meshes.insert_or_assign(mesh.get(), g).first->second;
}

void Renderer::Impl::add_mesh(const Basis& b, const ObjectDesc& o, std::uint32_t index, const glm::dvec3& lo,
                              const glm::dvec3& hi) {
  const GpuMesh& g = gpu_mesh(o.mesh);
  MeshInstance mi{};
  const glm::dvec3 offset = place(o, g.centre) - b.eye;
  const glm::dmat3 axes = glm::mat3_cast(unit_rotation(o.rotation)) * o.scale;
  for (int a = 0; a < 3; ++a) {
    mi.offset[a] = static_cast<float>(offset[a]);
    for (int r = 0; r < 3; ++r) mi.axes[3 * a + r] = static_cast<float>(axes[a][r]);
  }
  mi.index = index;
  added_instance.push_back(instances.size());
  added_mesh.push_back(&g);
  added.push_back(mi);
  // Its instance in the ball-and-box pass draws nothing; it holds the
  // object's box for the refinement levels' estimates.
  detail::Instance in = instance(b, 0.5 * (lo + hi), 0.5 * (hi - lo), true, index);
  in.kind = detail::kMesh;
  instances.push_back(in);
}

void Renderer::Impl::upload_meshes() {
  // Grouped by mesh (in the order added within a mesh): one draw a mesh.
  std::vector<std::size_t> order(added.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::stable_sort(order.begin(), order.end(),
                   [&](std::size_t a, std::size_t b) { return std::less<>()(added_mesh[a], added_mesh[b]); });
  mesh_instances.clear();
  slot_mesh.clear();
  mesh_groups.clear();
  mesh_slot.assign(instances.size(), 0);
  for (std::size_t k : order) {
    const auto slot = static_cast<std::uint32_t>(mesh_instances.size());
    mesh_slot[added_instance[k]] = slot;
    mesh_instances.push_back(added[k]);
    slot_mesh.push_back(added_mesh[k]);
    if (mesh_groups.empty() || mesh_groups.back().mesh != added_mesh[k])
      mesh_groups.push_back({added_mesh[k], slot, 0, 0});
    ++mesh_groups.back().count;
    mesh_groups.back().last = std::max(mesh_groups.back().last, added_instance[k]);
  }
  if (mesh_instances.empty()) return;
  glBindBuffer(GL_ARRAY_BUFFER, mesh_instance_vbo);
  if (mesh_instances.size() > mesh_instance_capacity) {
    mesh_instance_capacity = std::max(mesh_instances.size(), 2 * mesh_instance_capacity);
    glBufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(mesh_instance_capacity * sizeof(MeshInstance)), nullptr,
                 GL_STREAM_DRAW);
  }
  glBufferSubData(GL_ARRAY_BUFFER, 0, static_cast<GLsizeiptr>(mesh_instances.size() * sizeof(MeshInstance)),
                  mesh_instances.data());
}

void Renderer::Impl::mesh_uniforms(const Basis& b) {
  glUseProgram(mesh_program);
  glUniform3f(mu_right, static_cast<float>(b.right.x), static_cast<float>(b.right.y), static_cast<float>(b.right.z));
  glUniform3f(mu_up, static_cast<float>(b.up.x), static_cast<float>(b.up.y), static_cast<float>(b.up.z));
  glUniform3f(mu_f, static_cast<float>(b.f.x), static_cast<float>(b.f.y), static_cast<float>(b.f.z));
  glUniform2f(mu_tan, static_cast<float>(b.tanx), static_cast<float>(b.tany));
  glUniform2f(mu_range, static_cast<float>(b.near), static_cast<float>(b.far));
  glUseProgram(program);
}

void Renderer::Impl::draw_meshes(std::size_t n) {
  if (mesh_groups.empty() || n == 0) return;
  // Both faces: a mesh is a surface, and its triangles' winding is free.
  glUseProgram(mesh_program);
  glDisable(GL_CULL_FACE);
  for (const detail::MeshGroup& group : mesh_groups) {
    glBindVertexArray(group.mesh->vao);
    if (group.last < n) {
      glDrawElementsInstancedBaseInstance(GL_TRIANGLES, group.mesh->indices, GL_UNSIGNED_INT, nullptr,
                                          static_cast<GLsizei>(group.count), group.first);
      continue;
    }
    for (std::uint32_t slot = group.first; slot < group.first + group.count; ++slot)
      if (mesh_instances[slot].index <= n)
        glDrawElementsInstancedBaseInstance(GL_TRIANGLES, group.mesh->indices, GL_UNSIGNED_INT, nullptr, 1, slot);
  }
  glEnable(GL_CULL_FACE);
  glUseProgram(program);
  glBindVertexArray(vao);
}

void Renderer::Impl::draw_mesh(std::uint32_t slot) {
  const GpuMesh& g = *slot_mesh[slot];
  glUseProgram(mesh_program);
  glBindVertexArray(g.vao);
  glDisable(GL_CULL_FACE);
  glDrawElementsInstancedBaseInstance(GL_TRIANGLES, g.indices, GL_UNSIGNED_INT, nullptr, 1, slot);
  glEnable(GL_CULL_FACE);
  glUseProgram(program);
  glBindVertexArray(vao);
}

}  // namespace voxvis::render
