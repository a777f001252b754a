// format.cpp — reading the batch formats of format.h (format_write.cpp
// writes them); docs/formats.md is the contract.
//
// Parsing happens in two steps:
//  1. nlohmann::json::sax_parse builds a DOM through our own SAX handler
//     (DomBuilder, format_dom.cpp). The input is fed through CountingIterator, which counts the
//     lines of the characters the lexer consumes, so every SAX callback knows
//     the line of the token just read (syntax errors get their line this way).
//     The handler tracks the field path ("objects[3].radius") of every value
//     and rejects duplicate keys, which nlohmann's own DOM parser would
//     silently overwrite.
//  2. The DOM is validated field by field; an error names the path.
//  3. Only then, for the error's line, a second SAX pass (LineFinder, also in
//     format_dom.cpp) over the same text stops at the first key or array
//     element with that path and reports its line, falling back to the
//     nearest parent. Looking lines up lazily keeps valid documents fast:
//     recording the line of every field of a large scene up front would cost
//     as much as the parse itself.
// Nothing here throws on bad input: SAX callbacks return false to stop, and
// values are only read after their type has been checked.
#include "voxvis/format.h"
#include "voxvis/mesh.h"

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstddef>
#include <cstring>
#include <filesystem>
#include <istream>
#include <map>
#include <limits>
#include <string>
#include <string_view>
#include <unordered_map>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "format_dom.h"

namespace voxvis {

std::string FormatError::str() const {
  std::string out;
  if (!source.empty()) {
    out += source;
    if (line > 0) out += ":" + std::to_string(line);
    out += ": ";
  } else if (line > 0) {
    out += "line " + std::to_string(line) + ": ";
  }
  if (!field.empty()) out += field + ": ";
  out += message;
  return out;
}

namespace {

using detail::describe;
using detail::join_index;
using detail::join_key;
using detail::json;
using detail::line_of_path;
using detail::parse_dom;
using detail::quote_text;

constexpr std::string_view kSceneFormat = "voxvis-scene/1";
constexpr double kMaxId = 4294967295.0;

// ---------------------------------------------------------------------------
// Step 2: validation of the DOM.

/// Where errors go and how paths become lines.
class Checker {
 public:
  /// For a multi-line document (`text` not empty) lines are looked up by
  /// path; otherwise every error is on `fixed_line`.
  Checker(std::string_view source, std::string_view text, int fixed_line, FormatError* error)
      : source_(source), text_(text), fixed_line_(fixed_line), error_(error) {}

  /// Records an error for `field`, at the line of `line_path` (default: field).
  bool fail(const std::string& field, std::string message, const std::string* line_path = nullptr) {
    if (error_ != nullptr) {
      error_->source = std::string(source_);
      error_->line = line_of(line_path != nullptr ? *line_path : field);
      error_->field = field;
      error_->message = std::move(message);
    }
    return false;
  }

  int line_of(const std::string& path) const {
    return text_.empty() ? fixed_line_ : line_of_path(text_, path);
  }

  bool object(const json& v, const std::string& path) {
    if (v.is_object()) return true;
    return fail(path, "must be an object, got " + describe(v));
  }

  /// Rejects keys outside `allowed` (listed in the message).
  bool known_keys(const json& obj, const std::string& path,
                  std::initializer_list<std::string_view> allowed) {
    for (const auto& item : obj.items()) {
      const std::string& k = item.key();
      if (std::find(allowed.begin(), allowed.end(), std::string_view(k)) != allowed.end()) continue;
      std::string list;
      for (const std::string_view a : allowed) {
        if (!list.empty()) list += ", ";
        list += a;
      }
      const std::string key_path = join_key(path, k);
      return fail(path, "unknown key " + quote_text(k) + " (allowed: " + list + ")", &key_path);
    }
    return true;
  }

  /// The member `key` of `obj`, or an error naming it.
  const json* require(const json& obj, const std::string& path, const char* key,
                      std::string_view hint = {}) {
    const auto it = obj.find(key);
    if (it != obj.end()) return &*it;
    std::string msg = "missing required key " + quote_text(key);
    if (!hint.empty()) msg += " (" + std::string(hint) + ")";
    fail(path, std::move(msg));
    return nullptr;
  }

  bool number(const json& v, const std::string& path, double* out) {
    if (!v.is_number()) return fail(path, "must be a number, got " + describe(v));
    const double d = v.get<double>();
    if (!std::isfinite(d)) return fail(path, "must be finite, got " + number_text(d));
    *out = d;
    return true;
  }

  bool coordinate(const json& v, const std::string& path, double* out) {
    if (!number(v, path, out)) return false;
    if (std::fabs(*out) > kMaxCoordinate) {
      return fail(path, "magnitude must be at most " + number_text(kMaxCoordinate) + ", got " +
                            number_text(*out));
    }
    return true;
  }

  /// Three coordinates (magnitude at most kMaxCoordinate), or with
  /// `any_magnitude` three finite numbers (a direction).
  bool vec3(const json& v, const std::string& path, Vec3* out, bool any_magnitude = false) {
    if (!v.is_array()) return fail(path, "must be an array of 3 numbers, got " + describe(v));
    if (v.size() != 3) {
      return fail(path, "must be an array of 3 numbers, got " + std::to_string(v.size()) +
                            (v.size() == 1 ? " element" : " elements"));
    }
    for (std::size_t i = 0; i < 3; ++i) {
      double d = 0.0;
      if (!(any_magnitude ? number(v[i], join_index(path, i), &d) : coordinate(v[i], join_index(path, i), &d)))
        return false;
      (*out)[static_cast<glm::length_t>(i)] = d;
    }
    return true;
  }

  /// A rotation [w, x, y, z]: four finite numbers, a unit quaternion
  /// (validate_rotation).
  bool quat(const json& v, const std::string& path, Quat* out) {
    if (!v.is_array() || v.size() != 4)
      return fail(path, "must be a unit quaternion [w, x, y, z], got " + describe(v));
    double q[4];
    for (std::size_t i = 0; i < 4; ++i)
      if (!number(v[i], join_index(path, i), &q[i])) return false;
    const Quat r(q[0], q[1], q[2], q[3]);
    if (const Status st = validate_rotation(r, path); !st) return fail(st.field, st.message);
    *out = r;
    return true;
  }

  /// An integral value in [lo, hi] (integral floats like 7.0 count).
  bool integer(const json& v, const std::string& path, double lo, double hi, double* out,
               const char* what) {
    double d = 0.0;
    bool integral = false;
    if (v.is_number_unsigned()) {
      // Rounding to double is monotonic, so range checks on d stay exact
      // for the bounds used here (integers below 2^53).
      d = static_cast<double>(v.get<std::uint64_t>());
      integral = true;
    } else if (v.is_number_integer()) {
      d = static_cast<double>(v.get<std::int64_t>());
      integral = true;
    } else if (v.is_number_float()) {
      d = v.get<double>();
      integral = std::isfinite(d) && std::trunc(d) == d;
    }
    if (!v.is_number() || !integral || d < lo || d > hi) {
      return fail(path, std::string("must be ") + what + ", got " + describe(v));
    }
    *out = d;
    return true;
  }

  bool id(const json& v, const std::string& path, ObjectId* out) {
    double d = 0.0;
    if (!integer(v, path, 0.0, kMaxId, &d, "an integer in [0, 4294967295]")) return false;
    *out = static_cast<ObjectId>(d);
    return true;
  }

  bool boolean(const json& v, const std::string& path, bool* out) {
    if (!v.is_boolean()) return fail(path, "must be true or false, got " + describe(v));
    *out = v.get<bool>();
    return true;
  }

 private:
  std::string_view source_;
  std::string_view text_;
  int fixed_line_;
  FormatError* error_;
};

const char* axis_name(int axis) { return axis == 0 ? "x" : (axis == 1 ? "y" : "z"); }

/// The model references of one document: the loader, and the meshes loaded
/// so far by (resolved path, name), shared by the objects that name them.
struct ModelRefs {
  const SceneReadOptions* options = nullptr;
  std::map<std::pair<std::string, std::string>, std::shared_ptr<const Mesh>> loaded;
  MeshPlacementCheck placements;  // A loaded model placed many times is validated once.
};

/// A mesh object's "model" (and "model_name"): the mesh the loader gives.
bool load_model_ref(Checker& ck, const json& v, const std::string& path, ModelRefs* refs,
                    std::shared_ptr<const Mesh>* out) {
  const std::string mp = join_key(path, "model");
  for (const char* k : {"vertices", "triangles"}) {
    if (v.contains(k)) {
      const std::string kp = join_key(path, k);
      return ck.fail(path, "key " + quote_text(k) + " is not allowed with \"model\" (give the triangles inline or "
                                                   "by reference, not both)",
                     &kp);
    }
  }
  const json& model = v["model"];
  if (!model.is_string() || model.get_ref<const std::string&>().empty())
    return ck.fail(mp, "must be the path of a model file (a non-empty string), got " + describe(model));
  std::string name;
  if (const auto n = v.find("model_name"); n != v.end()) {
    const std::string np = join_key(path, "model_name");
    if (!n->is_string() || n->get_ref<const std::string&>().empty())
      return ck.fail(np, "must be the name of a node or mesh of the model (a non-empty string), got " + describe(*n));
    name = n->get_ref<const std::string&>();
  }
  const std::string& file = model.get_ref<const std::string&>();
  if (refs == nullptr || refs->options == nullptr || !refs->options->load_model)
    return ck.fail(mp, "cannot load the model file " + quote_text(file) +
                           ": this program reads scene files without a model importer (the voxvis commands replay, "
                           "verify, report, export and load have one); give the triangles inline (voxvis import "
                           "writes them)");
  std::filesystem::path resolved(file);
  if (resolved.is_relative() && !refs->options->base_dir.empty())
    resolved = std::filesystem::path(refs->options->base_dir) / resolved;
  const auto key = std::make_pair(resolved.string(), name);
  if (const auto it = refs->loaded.find(key); it != refs->loaded.end()) {
    *out = it->second;
    return true;
  }
  std::shared_ptr<const Mesh> mesh;
  const Status st = refs->options->load_model(key.first, name, &mesh);
  if (!st.ok || mesh == nullptr) {
    std::string what = "cannot load " + quote_text(key.first) + (name.empty() ? "" : " (" + quote_text(name) + ")");
    // The loader's errors name the file in their field: said once.
    const std::string why = st.ok ? std::string("the loader gave no mesh") : st.field == key.first ? st.message : st.str();
    return ck.fail(mp, what + ": " + why);
  }
  if (const Status vs = validate_mesh(*mesh, mp); !vs) return ck.fail(vs.field, vs.message);
  refs->loaded.emplace(key, mesh);
  *out = std::move(mesh);
  return true;
}

/// A mesh object's placement: "center", "rotation", "scale", then
/// validate_mesh_object's rules.
bool parse_placement(Checker& ck, const json& v, const std::string& path, ModelRefs* refs, ObjectDesc* obj) {
  const auto center = v.find("center");
  if (center != v.end() && !ck.vec3(*center, join_key(path, "center"), &obj->center)) return false;
  const auto rotation = v.find("rotation");
  if (rotation != v.end() && !ck.quat(*rotation, join_key(path, "rotation"), &obj->rotation)) return false;
  const auto scale = v.find("scale");
  if (scale != v.end() && !ck.number(*scale, join_key(path, "scale"), &obj->scale)) return false;
  const Status st = refs != nullptr ? refs->placements.check(*obj, path) : validate_mesh_object(*obj, path);
  if (!st) return ck.fail(st.field, st.message);
  return true;
}

/// A mesh object's own keys: "vertices" [[x, y, z], ...] and "triangles"
/// [[i, j, k], ...] (model space), "center" (where the model origin goes,
/// default [0, 0, 0]), "rotation" [w, x, y, z] (default [1, 0, 0, 0]) and
/// "scale" (default 1); then validate_mesh_object's rules. Or, instead of
/// "vertices" and "triangles", "model" (a model file's path) and optionally
/// "model_name", loaded through the reader options' loader.
bool parse_mesh(Checker& ck, const json& v, const std::string& path, ModelRefs* refs, ObjectDesc* obj) {
  for (const char* k : {"radius", "min", "max"}) {
    if (v.contains(k)) {
      const std::string kp = join_key(path, k);
      return ck.fail(path, "key " + quote_text(k) + " is not allowed for a mesh (give \"vertices\" and \"triangles\")",
                     &kp);
    }
  }
  if (v.contains("model")) {
    std::shared_ptr<const Mesh> loaded;
    if (!load_model_ref(ck, v, path, refs, &loaded)) return false;
    obj->shape = Shape::Mesh;
    obj->mesh = std::move(loaded);
    return parse_placement(ck, v, path, refs, obj);
  }
  if (v.contains("model_name")) {
    const std::string kp = join_key(path, "model_name");
    return ck.fail(path, "key \"model_name\" is only allowed with \"model\"", &kp);
  }
  auto mesh = std::make_shared<Mesh>();
  const json* verts = ck.require(v, path, "vertices", "[[x, y, z], ...]");
  if (verts == nullptr) return false;
  const std::string vp = join_key(path, "vertices");
  if (!verts->is_array()) return ck.fail(vp, "must be an array of [x, y, z], got " + describe(*verts));
  if (verts->size() > kMaxMeshVertices)
    return ck.fail(vp, "at most " + std::to_string(kMaxMeshVertices) + " vertices, got " + std::to_string(verts->size()));
  mesh->vertices.resize(verts->size());
  for (std::size_t i = 0; i < verts->size(); ++i)
    if (!ck.vec3((*verts)[i], join_index(vp, i), &mesh->vertices[i])) return false;
  const json* tris = ck.require(v, path, "triangles", "[[i, j, k], ...], indices into vertices");
  if (tris == nullptr) return false;
  const std::string tp = join_key(path, "triangles");
  if (!tris->is_array()) return ck.fail(tp, "must be an array of [i, j, k], got " + describe(*tris));
  if (tris->size() > kMaxMeshTriangles)
    return ck.fail(tp, "at most " + std::to_string(kMaxMeshTriangles) + " triangles, got " + std::to_string(tris->size()));
  mesh->triangles.resize(tris->size());
  for (std::size_t i = 0; i < tris->size(); ++i) {
    const json& t = (*tris)[i];
    const std::string ip = join_index(tp, i);
    if (!t.is_array() || t.size() != 3) return ck.fail(ip, "must be an array of 3 vertex indices, got " + describe(t));
    for (std::size_t k = 0; k < 3; ++k) {
      double d = 0.0;
      if (!ck.integer(t[k], join_index(ip, k), 0.0, 4294967295.0, &d, "a vertex index (an integer >= 0)")) return false;
      mesh->triangles[i][k] = static_cast<std::uint32_t>(d);
    }
  }
  obj->shape = Shape::Mesh;
  // The file names the mesh's keys on the object itself (no "mesh" key).
  if (const Status st = validate_mesh(*mesh, path); !st) return ck.fail(st.field, st.message);
  obj->mesh = std::move(mesh);
  // Its own mesh, placed once: nothing to share with the other objects.
  return parse_placement(ck, v, path, nullptr, obj);
}

bool parse_object(Checker& ck, const json& v, const std::string& path, ModelRefs* refs, ObjectDesc* out) {
  if (!ck.object(v, path)) return false;
  if (!ck.known_keys(v, path, {"id", "shape", "center", "radius", "min", "max", "dynamic", "max_speed",
                               "vertices", "triangles", "rotation", "scale", "model", "model_name"})) {
    return false;
  }
  ObjectDesc obj;
  const json* id = ck.require(v, path, "id");
  if (id == nullptr || !ck.id(*id, join_key(path, "id"), &obj.id)) return false;

  const json* shape = ck.require(v, path, "shape", "\"sphere\", \"box\" or \"mesh\"");
  if (shape == nullptr) return false;
  const std::string shape_path = join_key(path, "shape");
  if (!shape->is_string()) {
    return ck.fail(shape_path, "must be \"sphere\", \"box\" or \"mesh\", got " + describe(*shape));
  }
  const std::string& shape_name = shape->get_ref<const std::string&>();
  if (shape_name != "mesh") {
    for (const char* k : {"vertices", "triangles", "rotation", "scale", "model", "model_name"}) {
      if (v.contains(k)) {
        const std::string kp = join_key(path, k);
        return ck.fail(path, "key " + quote_text(k) + " is only allowed for a mesh", &kp);
      }
    }
  }
  if (shape_name == "mesh") {
    if (!parse_mesh(ck, v, path, refs, &obj)) return false;
  } else if (shape_name == "sphere") {
    obj.shape = Shape::Sphere;
    for (const char* k : {"min", "max"}) {
      if (v.contains(k)) {
        const std::string kp = join_key(path, k);
        return ck.fail(path, "key " + quote_text(k) + " is not allowed for a sphere (boxes only)", &kp);
      }
    }
    const json* center = ck.require(v, path, "center");
    if (center == nullptr || !ck.vec3(*center, join_key(path, "center"), &obj.center)) return false;
    const json* radius = ck.require(v, path, "radius");
    if (radius == nullptr) return false;
    const std::string rp = join_key(path, "radius");
    if (!ck.number(*radius, rp, &obj.radius)) return false;
    if (!(obj.radius > 0.0)) return ck.fail(rp, "must be > 0, got " + number_text(obj.radius));
    if (obj.radius > kMaxCoordinate) {
      return ck.fail(rp, "must be at most " + number_text(kMaxCoordinate) + ", got " +
                             number_text(obj.radius));
    }
  } else if (shape_name == "box") {
    obj.shape = Shape::Box;
    for (const char* k : {"center", "radius"}) {
      if (v.contains(k)) {
        const std::string kp = join_key(path, k);
        return ck.fail(path,
                       "key " + quote_text(k) + " is not allowed for a box (give \"min\" and \"max\")",
                       &kp);
      }
    }
    Vec3 lo{0.0}, hi{0.0};
    const json* jmin = ck.require(v, path, "min");
    if (jmin == nullptr || !ck.vec3(*jmin, join_key(path, "min"), &lo)) return false;
    const json* jmax = ck.require(v, path, "max");
    if (jmax == nullptr || !ck.vec3(*jmax, join_key(path, "max"), &hi)) return false;
    for (int a = 0; a < 3; ++a) {
      if (lo[a] > hi[a]) {
        return ck.fail(join_key(path, "max"),
                       std::string("must be >= min on every axis, got max.") + axis_name(a) +
                           " = " + number_text(hi[a]) + " < min." + axis_name(a) + " = " +
                           number_text(lo[a]));
      }
    }
    set_box_corners(lo, hi, &obj);
  } else {
    return ck.fail(shape_path, "unknown shape " + quote_text(shape_name, '"') +
                                   " (expected \"sphere\", \"box\" or \"mesh\")");
  }

  const auto dyn = v.find("dynamic");
  if (dyn != v.end() && !ck.boolean(*dyn, join_key(path, "dynamic"), &obj.dynamic)) return false;
  const auto speed = v.find("max_speed");
  const std::string sp = join_key(path, "max_speed");
  if (obj.dynamic) {
    if (speed == v.end()) {
      return ck.fail(path, "dynamic objects need max_speed (world units per second)");
    }
    if (!ck.number(*speed, sp, &obj.max_speed)) return false;
    if (!(obj.max_speed >= 0.0)) return ck.fail(sp, "must be >= 0, got " + number_text(obj.max_speed));
    if (obj.max_speed > kMaxCoordinate) {
      return ck.fail(sp, "must be at most " + number_text(kMaxCoordinate) + ", got " +
                             number_text(obj.max_speed));
    }
  } else if (speed != v.end()) {
    return ck.fail(sp, "is only allowed with \"dynamic\": true");
  }
  *out = obj;
  return true;
}

bool parse_scene_dom(Checker& ck, const json& root, ModelRefs* refs, SceneDesc* out) {
  const std::string top;
  if (!root.is_object()) {
    return ck.fail(top, "a scene must be a JSON object {\"format\": \"voxvis-scene/1\", ...}, got " +
                            describe(root));
  }
  const json* format = ck.require(root, top, "format", "expected \"voxvis-scene/1\"");
  if (format == nullptr) return false;
  if (!format->is_string() || format->get_ref<const std::string&>() != kSceneFormat) {
    return ck.fail("format", "unsupported format " + describe(*format) +
                                 ", expected \"voxvis-scene/1\"");
  }
  if (!ck.known_keys(root, top, {"format", "bounds", "grid", "objects"})) return false;

  SceneDesc desc;
  const json* bounds = ck.require(root, top, "bounds", "{\"min\": [x,y,z], \"max\": [x,y,z]}");
  if (bounds == nullptr || !ck.object(*bounds, "bounds")) return false;
  if (!ck.known_keys(*bounds, "bounds", {"min", "max"})) return false;
  const json* bmin = ck.require(*bounds, "bounds", "min");
  if (bmin == nullptr || !ck.vec3(*bmin, "bounds.min", &desc.bounds_min)) return false;
  const json* bmax = ck.require(*bounds, "bounds", "max");
  if (bmax == nullptr || !ck.vec3(*bmax, "bounds.max", &desc.bounds_max)) return false;
  for (int a = 0; a < 3; ++a) {
    if (!(desc.bounds_min[a] < desc.bounds_max[a])) {
      return ck.fail("bounds.max", std::string("must be > min on every axis, got max.") +
                                       axis_name(a) + " = " + number_text(desc.bounds_max[a]) +
                                       " <= min." + axis_name(a) + " = " +
                                       number_text(desc.bounds_min[a]));
    }
  }

  const auto grid = root.find("grid");
  if (grid != root.end()) {
    if (!grid->is_array() || grid->size() != 3) {
      return ck.fail("grid", "must be an array of 3 integers [nx, ny, nz], got " +
                                 (grid->is_array() ? std::to_string(grid->size()) + " elements"
                                                   : describe(*grid)));
    }
    glm::ivec3 res{1};
    for (std::size_t i = 0; i < 3; ++i) {
      const std::string gp = join_index("grid", i);
      double d = 0.0;
      if (!ck.integer((*grid)[i], gp, 1.0, std::numeric_limits<double>::infinity(), &d,
                      "an integer >= 1 (voxels along the axis)")) {
        return false;
      }
      if (d > kMaxResolution) {
        return ck.fail(gp, "must be at most " + std::to_string(kMaxResolution) +
                               " voxels per axis, got " + describe((*grid)[i]));
      }
      res[static_cast<glm::length_t>(i)] = static_cast<int>(d);
    }
    desc.grid = res;
  }

  const json* objects = ck.require(root, top, "objects", "an array, possibly empty");
  if (objects == nullptr) return false;
  if (!objects->is_array()) return ck.fail("objects", "must be an array, got " + describe(*objects));
  desc.objects.reserve(objects->size());
  std::unordered_map<ObjectId, std::size_t> seen;
  seen.reserve(objects->size());
  for (std::size_t i = 0; i < objects->size(); ++i) {
    const std::string path = join_index("objects", i);
    ObjectDesc obj;
    if (!parse_object(ck, (*objects)[i], path, refs, &obj)) return false;
    const auto [it, inserted] = seen.emplace(obj.id, i);
    if (!inserted) {
      return ck.fail(join_key(path, "id"),
                     "duplicate id " + std::to_string(obj.id) + ", first at line " +
                         std::to_string(ck.line_of(join_key(join_index("objects", it->second), "id"))) +
                         " (objects[" + std::to_string(it->second) + "])");
    }
    desc.objects.push_back(obj);
  }
  *out = std::move(desc);
  return true;
}

bool parse_frame_dom(Checker& ck, const json& root, FrameInput* out) {
  const std::string top;
  if (!root.is_object()) {
    return ck.fail(top, "a frame must be a JSON object {\"t\": ..., \"eye\": ..., ...}, got " +
                            describe(root));
  }
  if (!ck.known_keys(root, top, {"t", "eye", "dir", "up", "fov_y_deg", "aspect", "near", "far",
                                 "eye_extent", "omnidirectional", "horizon_s", "moves"})) {
    return false;
  }
  FrameInput frame;
  Camera& cam = frame.camera;
  const json* v = nullptr;
  if ((v = ck.require(root, top, "t", "seconds")) == nullptr || !ck.number(*v, "t", &frame.t)) {
    return false;
  }
  if (const Status ts = validate_time("t", frame.t); !ts) return ck.fail(ts.field, ts.message);
  struct Vec3Field {
    const char* key;
    Vec3* dst;
    bool direction;  ///< Any finite magnitude (validate_camera's rule).
  };
  for (const Vec3Field& f : {Vec3Field{"eye", &cam.eye, false}, Vec3Field{"dir", &cam.dir, true},
                             Vec3Field{"up", &cam.up, true}}) {
    if ((v = ck.require(root, top, f.key)) == nullptr || !ck.vec3(*v, f.key, f.dst, f.direction)) return false;
  }
  struct NumField {
    const char* key;
    double* dst;
  };
  for (const NumField& f : {NumField{"fov_y_deg", &cam.fov_y_deg}, NumField{"aspect", &cam.aspect},
                            NumField{"near", &cam.near}, NumField{"far", &cam.far}}) {
    if ((v = ck.require(root, top, f.key)) == nullptr || !ck.number(*v, f.key, f.dst)) return false;
  }
  // The region (optional; docs/formats.md, "Regions").
  if (const auto e = root.find("eye_extent"); e != root.end() && !ck.vec3(*e, "eye_extent", &cam.eye_extent, false))
    return false;
  if (const auto o = root.find("omnidirectional"); o != root.end() &&
                                                     !ck.boolean(*o, "omnidirectional", &cam.omnidirectional))
    return false;
  if (const auto h = root.find("horizon_s"); h != root.end() && !ck.number(*h, "horizon_s", &cam.horizon_s))
    return false;
  const Status cam_status = validate_camera(cam);
  if (!cam_status.ok) return ck.fail(cam_status.field, cam_status.message);

  const auto moves = root.find("moves");
  if (moves != root.end()) {
    if (!moves->is_array()) return ck.fail("moves", "must be an array, got " + describe(*moves));
    frame.moves.reserve(moves->size());
    std::unordered_map<ObjectId, std::size_t> seen;
    for (std::size_t i = 0; i < moves->size(); ++i) {
      const std::string path = join_index("moves", i);
      const json& m = (*moves)[i];
      if (!ck.object(m, path) || !ck.known_keys(m, path, {"id", "center", "rotation"})) return false;
      Move move;
      if ((v = ck.require(m, path, "id")) == nullptr || !ck.id(*v, join_key(path, "id"), &move.id)) {
        return false;
      }
      if ((v = ck.require(m, path, "center")) == nullptr ||
          !ck.vec3(*v, join_key(path, "center"), &move.center)) {
        return false;
      }
      if (const auto r = m.find("rotation"); r != m.end()) {
        if (!ck.quat(*r, join_key(path, "rotation"), &move.rotation)) return false;
        move.has_rotation = true;
      }
      const auto [it, inserted] = seen.emplace(move.id, i);
      if (!inserted) {
        return ck.fail(join_key(path, "id"), "duplicate id " + std::to_string(move.id) +
                                                 " in this frame's moves (also moves[" +
                                                 std::to_string(it->second) + "])");
      }
      frame.moves.push_back(move);
    }
  }
  *out = std::move(frame);
  return true;
}

}  // namespace

// ---------------------------------------------------------------------------
// Public entry points.

bool parse_scene(std::string_view text, std::string_view source, SceneDesc* out,
                 FormatError* error) {
  return parse_scene(text, source, out, error, SceneReadOptions{});
}

bool parse_scene(std::string_view text, std::string_view source, SceneDesc* out,
                 FormatError* error, const SceneReadOptions& options) {
  try {
    json root;
    int line = 0;
    std::string field, message;
    if (!parse_dom(text, &root, /*want_lines=*/true, &line, &field, &message)) {
      if (error != nullptr) *error = FormatError{std::string(source), line, field, message};
      return false;
    }
    Checker ck(source, text, 0, error);
    SceneDesc desc;
    ModelRefs refs;
    refs.options = &options;
    if (!parse_scene_dom(ck, root, &refs, &desc)) return false;
    if (out != nullptr) *out = std::move(desc);
    return true;
  } catch (const std::exception& e) {
    // Only resource exhaustion can get here (std::bad_alloc and the like).
    if (error != nullptr) {
      *error = FormatError{std::string(source), 0, "", std::string("cannot parse: ") + e.what()};
    }
    return false;
  }
}

bool parse_frame_line(std::string_view text, std::string_view source, int line, FrameInput* out,
                      FormatError* error) {
  try {
    if (text.find_first_not_of(" \t\r\n") == std::string_view::npos) {
      if (error != nullptr) {
        *error = FormatError{std::string(source), line, "", "empty line (expected a frame object)"};
      }
      return false;
    }
    json root;
    int err_line = 0;
    std::string field, message;
    if (!parse_dom(text, &root, /*want_lines=*/false, &err_line, &field, &message)) {
      if (error != nullptr) *error = FormatError{std::string(source), line, field, message};
      return false;
    }
    Checker ck(source, std::string_view{}, line, error);
    FrameInput frame;
    if (!parse_frame_dom(ck, root, &frame)) return false;
    frame.line = line;
    if (out != nullptr) *out = std::move(frame);
    return true;
  } catch (const std::exception& e) {
    if (error != nullptr) {
      *error = FormatError{std::string(source), line, "", std::string("cannot parse: ") + e.what()};
    }
    return false;
  }
}

bool is_blank_line(std::string_view line) {
  return line.find_first_not_of(" \t\r") == std::string_view::npos;
}

bool parse_frames(std::istream& in, std::string_view source, std::vector<FrameInput>* out,
                  FormatError* error) {
  int line_no = 0;
  try {
    FrameInput frame;
    std::string line;
    while (std::getline(in, line)) {
      ++line_no;
      if (is_blank_line(line)) continue;
      if (!parse_frame_line(line, source, line_no, &frame, error)) return false;
      out->push_back(std::move(frame));
    }
    if (in.bad()) {
      if (error != nullptr) {
        *error = FormatError{std::string(source), line_no, "",
                             std::string("cannot read: ") + std::strerror(errno)};
      }
      return false;
    }
    return true;
  } catch (const std::exception& e) {
    if (error != nullptr) {
      *error = FormatError{std::string(source), line_no, "", std::string("cannot read: ") + e.what()};
    }
    return false;
  }
}

int scene_field_line(std::string_view text, std::string_view field) {
  return line_of_path(text, std::string(field));
}

}  // namespace voxvis
