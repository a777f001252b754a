// format_write.cpp — writing the batch formats of format.h: scenes and
// frames as the readers (format.cpp) take them back, and result lines.
#include <charconv>
#include <cmath>
#include <cstdint>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

#include "format_text.h"
#include "voxvis/format.h"

namespace voxvis {
namespace {

using detail::append_int;
using detail::append_number;
using detail::append_vec3;

void append_quat(std::string& out, const Quat& q) {
  out += '[';
  append_number(out, q.w);
  out += ", ";
  append_number(out, q.x);
  out += ", ";
  append_number(out, q.y);
  out += ", ";
  append_number(out, q.z);
  out += ']';
}

/// A mesh object's placement keys after its id (always written, defaults
/// included, so that a reader sees them).
void append_mesh_placement(std::string& out, const ObjectDesc& o) {
  out += ", \"shape\": \"mesh\", \"center\": ";
  append_vec3(out, o.center);
  out += ", \"rotation\": ";
  append_quat(out, o.rotation);
  out += ", \"scale\": ";
  append_number(out, o.scale);
}

/// A mesh's keys after its placement: inline vertices and triangles.
void append_mesh_data(std::string& out, const Mesh* m) {
  out += ", \"vertices\": [";
  for (std::size_t i = 0; m != nullptr && i < m->vertices.size(); ++i) {
    if (i > 0) out += ", ";
    append_vec3(out, m->vertices[i]);
  }
  out += "], \"triangles\": [";
  for (std::size_t i = 0; m != nullptr && i < m->triangles.size(); ++i) {
    if (i > 0) out += ", ";
    out += '[';
    for (int k = 0; k < 3; ++k) {
      if (k > 0) out += ", ";
      append_int(out, m->triangles[i][static_cast<std::size_t>(k)]);
    }
    out += ']';
  }
  out += ']';
}

/// The text before the objects.
void append_scene_head(std::string& out, const SceneDesc& scene) {
  out += "{\n  \"format\": \"voxvis-scene/1\",\n  \"bounds\": {\"min\": ";
  append_vec3(out, scene.bounds_min);
  out += ", \"max\": ";
  append_vec3(out, scene.bounds_max);
  out += "},\n";
  if (scene.grid) {
    out += "  \"grid\": [";
    append_int(out, scene.grid->x);
    out += ", ";
    append_int(out, scene.grid->y);
    out += ", ";
    append_int(out, scene.grid->z);
    out += "],\n";
  }
  out += "  \"objects\": [";
}

/// One object's text, from its opening brace to its closing one; a mesh's
/// vertices and triangles only when `mesh_data`.
void append_object(std::string& out, const ObjectDesc& o, bool mesh_data) {
  out += "{\"id\": ";
  append_int(out, o.id);
  if (o.shape == Shape::Mesh) {
    append_mesh_placement(out, o);
    if (mesh_data) append_mesh_data(out, o.mesh.get());
  } else if (o.shape == Shape::Box) {
    out += ", \"shape\": \"box\", \"min\": ";
    append_vec3(out, o.center - o.half_extent);
    out += ", \"max\": ";
    append_vec3(out, o.center + o.half_extent);
  } else {
    out += ", \"shape\": \"sphere\", \"center\": ";
    append_vec3(out, o.center);
    out += ", \"radius\": ";
    append_number(out, o.radius);
  }
  if (o.dynamic) {
    out += ", \"dynamic\": true, \"max_speed\": ";
    append_number(out, o.max_speed);
  }
  out += '}';
}

/// The length of append_mesh_data's text, one vertex or triangle at a time
/// (the text of a large mesh is never held whole).
std::uint64_t mesh_data_bytes(const Mesh* m) {
  std::string one;
  append_mesh_data(one, nullptr);  // The keys and brackets alone.
  std::uint64_t n = one.size();
  if (m == nullptr) return n;
  for (const Vec3& v : m->vertices) {
    one.clear();
    append_vec3(one, v);
    n += one.size();
  }
  for (const auto& t : m->triangles) {
    one.clear();
    for (const std::uint32_t i : t) append_int(one, i);
    n += one.size() + 6;  // "[", "]" and two ", ".
  }
  const auto separators = [](std::size_t k) { return k > 0 ? 2 * (std::uint64_t{k} - 1) : 0; };
  return n + separators(m->vertices.size()) + separators(m->triangles.size());
}

constexpr std::string_view kFirstObject = "\n    ", kNextObject = ",\n    ";
constexpr std::string_view kEndEmpty = "]\n}\n", kEnd = "\n  ]\n}\n";

}  // namespace

using detail::append_int;
using detail::append_number;
using detail::append_vec3;

std::string scene_to_json(const SceneDesc& scene) {
  std::string out;
  out.reserve(128 + scene.objects.size() * 96);
  append_scene_head(out, scene);
  bool first = true;
  for (const ObjectDesc& o : scene.objects) {
    out += first ? kFirstObject : kNextObject;
    first = false;
    append_object(out, o, true);
  }
  out += first ? kEndEmpty : kEnd;
  return out;
}

std::uint64_t scene_json_bytes(const SceneDesc& scene, std::uint64_t* inline_meshes) {
  std::string text;
  append_scene_head(text, scene);
  std::uint64_t total = text.size(), meshes = 0;
  std::unordered_map<const Mesh*, std::uint64_t> mesh_text;  // Each distinct mesh's, once.
  for (std::size_t i = 0; i < scene.objects.size(); ++i) {
    const ObjectDesc& o = scene.objects[i];
    text.clear();
    append_object(text, o, false);
    total += (i == 0 ? kFirstObject : kNextObject).size() + text.size();
    if (o.shape != Shape::Mesh) continue;
    const auto [it, fresh] = mesh_text.try_emplace(o.mesh.get(), 0);
    if (fresh) it->second = mesh_data_bytes(o.mesh.get());
    meshes += it->second;
  }
  if (inline_meshes != nullptr) *inline_meshes = meshes;
  return meshes + total + (scene.objects.empty() ? kEndEmpty : kEnd).size();
}

std::string frame_to_json(const FrameInput& frame) {
  std::string out;
  out.reserve(256 + frame.moves.size() * 64);
  const Camera& c = frame.camera;
  out += "{\"t\": ";
  append_number(out, frame.t);
  out += ", \"eye\": ";
  append_vec3(out, c.eye);
  out += ", \"dir\": ";
  append_vec3(out, c.dir);
  out += ", \"up\": ";
  append_vec3(out, c.up);
  out += ", \"fov_y_deg\": ";
  append_number(out, c.fov_y_deg);
  out += ", \"aspect\": ";
  append_number(out, c.aspect);
  out += ", \"near\": ";
  append_number(out, c.near);
  out += ", \"far\": ";
  append_number(out, c.far);
  // The region's fields only when off their defaults: a point camera's line
  // is what it always was.
  if (c.eye_extent != Vec3(0.0)) {
    out += ", \"eye_extent\": ";
    append_vec3(out, c.eye_extent);
  }
  if (c.omnidirectional) out += ", \"omnidirectional\": true";
  if (c.horizon_s != 0.0) {
    out += ", \"horizon_s\": ";
    append_number(out, c.horizon_s);
  }
  if (!frame.moves.empty()) {
    out += ", \"moves\": [";
    bool first = true;
    for (const Move& m : frame.moves) {
      if (!first) out += ", ";
      first = false;
      out += "{\"id\": ";
      append_int(out, m.id);
      out += ", \"center\": ";
      append_vec3(out, m.center);
      if (m.has_rotation) {
        out += ", \"rotation\": ";
        append_quat(out, m.rotation);
      }
      out += '}';
    }
    out += ']';
  }
  out += '}';
  return out;
}

std::string result_to_json(std::size_t frame_index, const FrameResult& result) {
  std::string out;
  out.reserve(320 + (result.pvs.size() + result.wake.size()) * 8);
  const auto ids = [&out](const char* name, const std::vector<ObjectId>& v) {
    out += name;
    out += '[';
    for (std::size_t i = 0; i < v.size(); ++i) {
      if (i > 0) out += ',';
      append_int(out, v[i]);
    }
    out += ']';
  };
  const FrameStats& s = result.stats;
  out += "{\"frame\":";
  append_int(out, frame_index);
  ids(",\"pvs\":", result.pvs);
  ids(",\"wake\":", result.wake);
  out += ",\"stats\":{\"time_us\":";
  {
    const double t = std::isfinite(s.time_us) ? s.time_us : 0.0;
    char buf[64];
    const auto r = std::to_chars(buf, buf + sizeof buf, t, std::chars_format::fixed, 3);
    out.append(buf, r.ptr);
  }
  const auto micros = [&out](const char* name, double v) {
    out += ",\"";
    out += name;
    out += "\":";
    char buf[64];
    const auto r = std::to_chars(buf, buf + sizeof buf, std::isfinite(v) ? v : 0.0, std::chars_format::fixed, 3);
    out.append(buf, r.ptr);
  };
  micros("traverse_us", s.traverse_us);
  micros("render_us", s.render_us);
  micros("retest_us", s.retest_us);
  const auto count = [&out](const char* name, std::uint64_t v) {
    out += ",\"";
    out += name;
    out += "\":";
    append_int(out, v);
  };
  count("voxels_visited", s.voxels_visited);
  count("shells", s.shells);
  count("objects_discretized", s.objects_discretized);
  count("tbvs_created", s.tbvs_created);
  count("tbvs_revealed", s.tbvs_revealed);
  count("tbvs_expired", s.tbvs_expired);
  count("tbvs_active", s.tbvs_active);
  count("speed_violations", s.speed_violations);
  count("outside_tested", s.outside_tested);
  count("pvs_size", s.pvs_size);
  out += ",\"early_exit\":";
  out += s.early_exit ? "true" : "false";
  out += ",\"frustum_fallback\":";
  out += s.frustum_fallback ? "true" : "false";
  if (s.region) out += ",\"region\":true";  // Only for regions (docs/formats.md).
  count("front_voxels_culled", s.front_voxels_culled);
  count("front_objects_culled", s.front_objects_culled);
  if (s.ob_width > 0) {
    // Only with the occlusion buffer on (docs/formats.md).
    count("ob_width", s.ob_width);
    count("ob_voxels_culled", s.ob_voxels_culled);
    count("ob_objects_culled", s.ob_objects_culled);
    count("ob_occluders", s.ob_occluders);
    count("ob_pixels_written", s.ob_pixels_written);
    count("cells_visited", s.cells_visited);
    count("cells_hidden", s.cells_hidden);
    count("cells_whole", s.cells_whole);
  }
  out += "}}";
  return out;
}

}  // namespace voxvis
