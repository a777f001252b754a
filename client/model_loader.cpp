// model_loader.cpp — model references loaded in a child process.
//
// The child runs import::load_model_mesh and writes its answer on a pipe:
//   ok:    'M', vertex count (u64), triangle count (u64), the vertices
//          (3 doubles each), the triangles (3 u32 each);
//   error: 'E', field length (u64), field, message length (u64), message.
// The parent reads it whole, then waits for the child; a child that dies or
// outlives the timeout gives an error naming the file.
#include "model_loader.h"

#include "child_process.h"

#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <memory>
#include <string>

#include "voxvis/import.h"
#include "voxvis/mesh.h"

namespace voxvis::cli {
namespace {

bool write_all(int fd, const void* data, std::size_t size) {
  const auto* p = static_cast<const char*>(data);
  while (size > 0) {
    const ssize_t n = ::write(fd, p, size);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return false;
    p += n;
    size -= static_cast<std::size_t>(n);
  }
  return true;
}

bool write_u64(int fd, std::uint64_t v) { return write_all(fd, &v, sizeof v); }

void child(int fd, const std::string& path, const std::string& name) {
  std::shared_ptr<const Mesh> mesh;
  Status st;
  try {
    st = import::load_model_mesh(path, name, &mesh);
  } catch (const std::exception& e) {
    st = Status::Error(path, std::string("cannot import: ") + e.what());
  }
  if (st.ok && mesh != nullptr) {
    write_all(fd, "M", 1) && write_u64(fd, mesh->vertices.size()) && write_u64(fd, mesh->triangles.size()) &&
        write_all(fd, mesh->vertices.data(), mesh->vertices.size() * sizeof(Vec3)) &&
        write_all(fd, mesh->triangles.data(), mesh->triangles.size() * sizeof(mesh->triangles[0]));
  } else {
    write_all(fd, "E", 1) && write_u64(fd, st.field.size()) && write_all(fd, st.field.data(), st.field.size()) &&
        write_u64(fd, st.message.size()) && write_all(fd, st.message.data(), st.message.size());
  }
}

/// Reads the child's answer; false when it is cut short or malformed.
bool decode(const std::string& data, Status* st, std::shared_ptr<const Mesh>* out) {
  std::size_t at = 1;
  const auto u64 = [&](std::uint64_t* v) {
    if (data.size() - at < sizeof *v) return false;
    std::memcpy(v, data.data() + at, sizeof *v);
    at += sizeof *v;
    return true;
  };
  if (data.empty()) return false;
  if (data[0] == 'E') {
    std::uint64_t n = 0;
    if (!u64(&n) || data.size() - at < n) return false;
    std::string field = data.substr(at, n);
    at += n;
    if (!u64(&n) || data.size() - at < n) return false;
    *st = Status::Error(std::move(field), data.substr(at, n));
    return true;
  }
  std::uint64_t nv = 0, nt = 0;
  if (data[0] != 'M' || !u64(&nv) || !u64(&nt) || nv > kMaxMeshVertices || nt > kMaxMeshTriangles) return false;
  auto mesh = std::make_shared<Mesh>();
  mesh->vertices.resize(nv);
  mesh->triangles.resize(nt);
  const std::size_t vbytes = nv * sizeof(Vec3), tbytes = nt * sizeof(mesh->triangles[0]);
  if (data.size() - at != vbytes + tbytes) return false;
  std::memcpy(mesh->vertices.data(), data.data() + at, vbytes);
  std::memcpy(mesh->triangles.data(), data.data() + at + vbytes, tbytes);
  *out = std::move(mesh);
  *st = Status::Ok();
  return true;
}

Status load_isolated(const std::string& path, const std::string& name, double timeout_s,
                     std::shared_ptr<const Mesh>* out) {
  std::string data;
  const ChildOutcome c = run_in_child(
      [&](int fd) {
        child(fd, path, name);
        return 0;
      },
      timeout_s, [&](std::string_view chunk) { data.append(chunk); }, default_child_memory_bytes());
  if (!c.error.empty()) return Status::Error(path, "cannot start the model reader: " + c.error);
  if (c.timed_out)
    return Status::Error(path, "no result after " + number_text(timeout_s) +
                                   " s: the model reader is stuck on this file (a malformed file can make it loop)");
  if (c.signal() != 0)
    return Status::Error(path, "the model reader crashed on this file (" + signal_text(c.signal()) +
                                   "): it is malformed, uses a feature the reader (assimp) mishandles, or needs "
                                   "more than the " + std::to_string(default_child_memory_bytes() >> 20) +
                                   " MiB a model reader may take");
  Status st;
  if (!decode(data, &st, out)) return Status::Error(path, "the model reader ended without an answer");
  return st;
}

}  // namespace

SceneReadOptions scene_read_options(const std::string& scene_path, int* loaded, double timeout_s) {
  SceneReadOptions options;
  options.base_dir = std::filesystem::path(scene_path).parent_path().string();
  options.load_model = [loaded, timeout_s](const std::string& path, const std::string& name,
                                           std::shared_ptr<const Mesh>* out) {
    if (loaded != nullptr) ++*loaded;
    return load_isolated(path, name, timeout_s, out);
  };
  return options;
}

}  // namespace voxvis::cli
