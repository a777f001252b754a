// import.cpp — model files to mesh objects through assimp (voxvis/import.h).
//
// assimp reads the file and post-processes it: Triangulate (polygons to
// triangles), JoinIdenticalVertices (one vertex per position: assimp's
// readers emit one per face corner), SortByPType (points and lines apart
// from triangles, to be skipped and counted), RemoveComponent (normals,
// texture coordinates, colours, bones, animations, textures, lights, cameras
// and materials: voxvis needs positions only, and dropping them first lets
// JoinIdenticalVertices join by position) and ValidateDataStructure (indices
// in range, counts consistent; a file that fails is refused with assimp's
// message). FindDegenerates is not used: its test is assimp's (equal
// positions, or an area below an epsilon that would drop small but valid
// triangles of a model in millimetres); voxvis's rule is exact (the edge
// vectors' cross product in double is zero), applied here to the final
// vertices, after the placement, and every triangle dropped is counted.
#include "voxvis/import.h"

#include "model_folder_io.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <limits>
#include <memory>
#include <string>
#include <system_error>
#include <unordered_set>
#include <utility>
#include <vector>

#include <assimp/Importer.hpp>
#include <assimp/ProgressHandler.hpp>
#include <assimp/config.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <glm/gtc/matrix_access.hpp>
#include <glm/gtc/quaternion.hpp>
#include <glm/mat3x3.hpp>
#include <glm/mat4x4.hpp>

namespace voxvis::import {
namespace {

using glm::dmat3;
using glm::dmat4;

/// Deepest node hierarchy walked, and most nodes: a malformed file may claim
/// millions of nested nodes; real models stay far below.
constexpr std::size_t kMaxDepth = 4096;
constexpr std::size_t kMaxNodes = std::size_t{1} << 24;

unsigned post_processing() {
  return aiProcess_Triangulate | aiProcess_JoinIdenticalVertices | aiProcess_SortByPType |
         aiProcess_RemoveComponent | aiProcess_ValidateDataStructure;
}

void configure(Assimp::Importer& importer) {
  importer.SetPropertyInteger(AI_CONFIG_PP_RVC_FLAGS,
                              aiComponent_NORMALS | aiComponent_TANGENTS_AND_BITANGENTS | aiComponent_COLORS |
                                  aiComponent_TEXCOORDS | aiComponent_BONEWEIGHTS | aiComponent_ANIMATIONS |
                                  aiComponent_TEXTURES | aiComponent_LIGHTS | aiComponent_CAMERAS |
                                  aiComponent_MATERIALS);
}

std::string quote_name(const std::string& s) {
  std::string out = "'";
  for (const char c : s) {
    if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) {
      static const char* hex = "0123456789abcdef";
      out += "\\x";
      out += hex[(static_cast<unsigned char>(c) >> 4) & 0xf];
      out += hex[static_cast<unsigned char>(c) & 0xf];
    } else {
      out += c;
    }
  }
  return out + "'";
}

std::string name_of(const aiString& s) { return std::string(s.C_Str(), std::min<std::size_t>(s.length, MAXLEN - 1)); }

dmat4 to_dmat4(const aiMatrix4x4& m) {
  // aiMatrix4x4 is row-major and transforms column vectors, as glm does.
  dmat4 r(1.0);
  for (int row = 0; row < 4; ++row)
    for (int col = 0; col < 4; ++col) r[col][row] = static_cast<double>(m[static_cast<unsigned>(row)][col]);
  return r;
}

bool finite(const dmat4& m) {
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r)
      if (!std::isfinite(m[c][r])) return false;
  return true;
}

/// A node that holds meshes, with its world matrix.
struct Instance {
  const aiNode* node = nullptr;
  std::string name;
  std::string path;
  dmat4 world{1.0};
};

/// Where an object's vertices go in the file: stored = bake * model + shift,
/// placed by center + scale * rotate(rotation, stored).
struct Placement {
  dmat3 bake{1.0};
  Vec3 shift{0.0};
  Vec3 center{0.0};
  Quat rotation{1.0, 0.0, 0.0, 0.0};
  double scale = 1.0;
};

Placement static_placement(const dmat4& world) {
  Placement p;
  p.bake = dmat3(world);
  p.shift = Vec3(world[3]);
  return p;
}

/// The rotation of the polar decomposition m = R S (S symmetric positive
/// definite); for a mirroring m (negative determinant) that of -m, so that R
/// is a rotation and the mirror goes to the baked part. Identity when m is
/// singular (everything is baked).
dmat3 polar_rotation(const dmat3& m) {
  const double det = glm::determinant(m);
  if (!(std::fabs(det) > 0.0) || !std::isfinite(det)) return dmat3(1.0);
  dmat3 x = det < 0.0 ? -m : m;
  for (int i = 0; i < 64; ++i) {
    const dmat3 next = 0.5 * (x + glm::transpose(glm::inverse(x)));
    double diff = 0.0;
    for (int c = 0; c < 3; ++c)
      for (int r = 0; r < 3; ++r) diff = std::max(diff, std::fabs(next[c][r] - x[c][r]));
    x = next;
    if (diff < 1e-15) break;
  }
  return x;
}

/// A dynamic object's placement: centre = the node's world translation,
/// rotation = its world rotation, scale = its uniform scale when the rest of
/// its matrix is one (within 1e-6), else 1 with the scale baked; whatever
/// the rotation and scale leave of the matrix (a float file's rounding, a
/// non-uniform scale, shear, a mirror) is baked into the vertices, so that
/// the placed vertices are where the world matrix puts them.
Placement dynamic_placement(const dmat4& world) {
  Placement p;
  const dmat3 m(world);
  p.center = Vec3(world[3]);
  const dmat3 r = polar_rotation(m);
  p.rotation = unit_rotation(glm::quat_cast(r));
  const dmat3 rq = glm::mat3_cast(p.rotation);
  dmat3 rest = glm::transpose(rq) * m;  // ≈ S, symmetric.
  const double det = glm::determinant(rest);
  if (det > 0.0 && std::isfinite(det)) {
    const double s = std::cbrt(det);
    bool uniform = true;
    for (int c = 0; c < 3; ++c)
      for (int row = 0; row < 3; ++row)
        if (std::fabs(rest[c][row] / s - (c == row ? 1.0 : 0.0)) > 1e-6) uniform = false;
    if (uniform) {
      p.scale = s;
      rest = rest / s;
    }
  }
  p.bake = rest;
  return p;
}

/// An object's triangles as they accumulate, merged from meshes.
struct Builder {
  std::vector<Vec3> vertices;
  std::vector<std::array<std::uint32_t, 3>> triangles;
  std::vector<std::string> meshes;
};

Status fail(const std::string& source, const std::string& message) { return Status::Error(source, message); }

/// Appends the triangles of `mesh`, its vertices mapped by `p`'s bake.
Status add_mesh(const aiMesh* mesh, const Placement& p, const std::string& source, const std::string& node,
                Builder* b, ImportStats* stats) {
  const std::string where = "node " + quote_name(node) + ", mesh " + quote_name(name_of(mesh->mName));
  if ((mesh->mPrimitiveTypes & aiPrimitiveType_TRIANGLE) == 0 || mesh->mVertices == nullptr ||
      mesh->mFaces == nullptr) {
    if ((mesh->mPrimitiveTypes & (aiPrimitiveType_POINT | aiPrimitiveType_LINE)) != 0)
      stats->points_lines += mesh->mNumFaces;
    else
      ++stats->empty_meshes;
    return Status::Ok();
  }
  const std::size_t base = b->vertices.size();
  if (base + mesh->mNumVertices > std::numeric_limits<std::uint32_t>::max())
    return fail(source, where + ": more vertices than one object may hold; use --split meshes");
  b->vertices.reserve(base + mesh->mNumVertices);
  for (unsigned i = 0; i < mesh->mNumVertices; ++i) {
    const aiVector3D& v = mesh->mVertices[i];
    b->vertices.push_back(p.bake * Vec3(v.x, v.y, v.z) + p.shift);
  }
  std::size_t kept = 0;
  for (unsigned f = 0; f < mesh->mNumFaces; ++f) {
    const aiFace& face = mesh->mFaces[f];
    if (face.mNumIndices != 3 || face.mIndices == nullptr) {
      ++stats->points_lines;
      continue;
    }
    std::array<std::uint32_t, 3> t{};
    for (unsigned k = 0; k < 3; ++k) {
      if (face.mIndices[k] >= mesh->mNumVertices)
        return fail(source, where + ": face " + std::to_string(f) + " refers to vertex " +
                                std::to_string(face.mIndices[k]) + " of " + std::to_string(mesh->mNumVertices));
      t[k] = static_cast<std::uint32_t>(base + face.mIndices[k]);
    }
    for (const std::uint32_t k : t) {
      const Vec3& v = b->vertices[k];
      const double m = std::max({std::fabs(v.x), std::fabs(v.y), std::fabs(v.z)});
      if (!(m <= kMaxCoordinate))
        return fail(source, where + ": vertex " + std::to_string(k - base) + " lies at (" + number_text(v.x) + ", " +
                                number_text(v.y) + ", " + number_text(v.z) + ") after the node transforms; voxvis " +
                                "takes finite coordinates of magnitude at most " + number_text(kMaxCoordinate));
    }
    const Vec3& a = b->vertices[t[0]];
    const Vec3 n = glm::cross(b->vertices[t[1]] - a, b->vertices[t[2]] - a);
    if (!(std::max({std::fabs(n.x), std::fabs(n.y), std::fabs(n.z)}) > 0.0)) {
      ++stats->degenerate;
      continue;
    }
    b->triangles.push_back(t);
    ++kept;
  }
  if (kept == 0) {
    ++stats->empty_meshes;
  } else {
    ++stats->mesh_instances;
    b->meshes.push_back(name_of(mesh->mName));
  }
  return Status::Ok();
}

/// The builder's triangles as a mesh object (its unused vertices dropped),
/// appended to `out`; nothing when it holds no triangle.
Status finish(Builder&& b, const Placement& p, ImportedObject&& proto, ImportStats* stats,
              std::vector<ImportedObject>* out) {
  if (b.triangles.empty()) {
    ++stats->empty_objects;
    return Status::Ok();
  }
  std::vector<std::uint32_t> remap(b.vertices.size(), std::numeric_limits<std::uint32_t>::max());
  auto mesh = std::make_shared<Mesh>();
  for (auto& t : b.triangles)
    for (std::uint32_t& k : t) {
      if (remap[k] == std::numeric_limits<std::uint32_t>::max()) {
        remap[k] = static_cast<std::uint32_t>(mesh->vertices.size());
        mesh->vertices.push_back(b.vertices[k]);
      }
      k = remap[k];
    }
  mesh->triangles = std::move(b.triangles);
  const std::string what = "object " + quote_name(proto.name) + (proto.node.empty() ? "" : " (node " + quote_name(proto.node) + ")");
  if (mesh->vertices.size() > kMaxMeshVertices || mesh->triangles.size() > kMaxMeshTriangles)
    return fail(proto.source, what + ": " + std::to_string(mesh->vertices.size()) + " vertices and " +
                                  std::to_string(mesh->triangles.size()) + " triangles, more than one mesh may hold (" +
                                  std::to_string(kMaxMeshVertices) + " and " + std::to_string(kMaxMeshTriangles) +
                                  "); split it (--split meshes)");
  stats->triangles += mesh->triangles.size();
  stats->vertices += mesh->vertices.size();
  ObjectDesc& o = proto.desc;
  o.shape = Shape::Mesh;
  o.center = p.center;
  o.rotation = p.rotation;
  o.scale = p.scale;
  o.mesh = std::move(mesh);
  if (const Status st = validate_mesh_object(o, "mesh"); !st) return fail(proto.source, what + ": " + st.str());
  proto.meshes = std::move(b.meshes);
  out->push_back(std::move(proto));
  return Status::Ok();
}

/// The nodes of `scene` that hold meshes, depth first, children in order.
Status walk(const aiScene* scene, const std::string& source, std::vector<Instance>* out, ImportStats* stats) {
  if (scene->mRootNode == nullptr) return fail(source, "the model has no node hierarchy");
  struct Item {
    const aiNode* node;
    dmat4 parent;
    std::string parent_path;
    std::size_t depth;
  };
  std::vector<Item> stack{{scene->mRootNode, dmat4(1.0), "", 0}};
  while (!stack.empty()) {
    Item it = std::move(stack.back());
    stack.pop_back();
    const aiNode* node = it.node;
    if (node == nullptr) continue;
    if (it.depth > kMaxDepth) return fail(source, "node hierarchy deeper than " + std::to_string(kMaxDepth));
    if (++stats->nodes > kMaxNodes) return fail(source, "more than " + std::to_string(kMaxNodes) + " nodes");
    Instance inst;
    inst.node = node;
    inst.name = name_of(node->mName);
    inst.path = it.parent_path.empty() ? inst.name : it.parent_path + "/" + inst.name;
    inst.world = it.parent * to_dmat4(node->mTransformation);
    if (!finite(inst.world)) return fail(source, "node " + quote_name(inst.path) + ": its world transform is not finite");
    for (unsigned i = 0; i < node->mNumMeshes; ++i)
      if (node->mMeshes == nullptr || node->mMeshes[i] >= scene->mNumMeshes || scene->mMeshes[node->mMeshes[i]] == nullptr)
        return fail(source, "node " + quote_name(inst.path) + " refers to a mesh the model does not have");
    for (unsigned c = node->mNumChildren; c-- > 0;)
      if (node->mChildren != nullptr) stack.push_back({node->mChildren[c], inst.world, inst.path, it.depth + 1});
    if (node->mNumMeshes > 0) out->push_back(std::move(inst));
  }
  return Status::Ok();
}

bool matches(const std::vector<std::string>& names, const std::string& a, const std::string& b, const std::string& c,
             std::vector<bool>* used) {
  bool any = false;
  for (std::size_t i = 0; i < names.size(); ++i)
    if (names[i] == a || names[i] == b || names[i] == c) {
      (*used)[i] = true;
      any = true;
    }
  return any;
}

/// One imported scene's objects, following `options`.
Status convert(const aiScene* scene, const std::string& source, const ImportOptions& options,
               std::vector<bool>* used, ImportResult* out) {
  ImportStats stats;
  std::vector<Instance> nodes;
  if (const Status st = walk(scene, source, &nodes, &stats); !st) return st;
  std::vector<ImportedObject> objects;
  const auto proto = [&](std::string name, const Instance* inst) {
    ImportedObject o;
    o.name = std::move(name);
    o.source = source;
    if (inst != nullptr) o.node = inst->path;
    return o;
  };
  const auto dynamic_of = [&](ImportedObject& o, const std::string& node_name) {
    if (matches(options.dynamic_names, o.name, node_name, o.node, used)) {
      o.desc.dynamic = true;
      o.desc.max_speed = options.max_speed;
    }
    return o.desc.dynamic;
  };
  if (options.split == Split::Whole) {
    ImportedObject o = proto(std::filesystem::path(source).filename().string(), nullptr);
    // A whole file, dynamic or not, is placed as it lies: centre 0, the
    // node transforms baked.
    dynamic_of(o, "");
    Builder b;
    for (const Instance& inst : nodes)
      for (unsigned i = 0; i < inst.node->mNumMeshes; ++i)
        if (const Status st = add_mesh(scene->mMeshes[inst.node->mMeshes[i]], static_placement(inst.world), source,
                                       inst.path, &b, &stats);
            !st)
          return st;
    if (const Status st = finish(std::move(b), Placement{}, std::move(o), &stats, &objects); !st) return st;
  } else {
    for (const Instance& inst : nodes) {
      const unsigned count = options.split == Split::Nodes ? 1u : inst.node->mNumMeshes;
      for (unsigned k = 0; k < count; ++k) {
        std::string name = inst.name;
        if (options.split == Split::Meshes) {
          const std::string mesh_name = name_of(scene->mMeshes[inst.node->mMeshes[k]]->mName);
          if (!mesh_name.empty()) name = mesh_name;
        }
        ImportedObject o = proto(name, &inst);
        const Placement p = dynamic_of(o, inst.name) ? dynamic_placement(inst.world) : static_placement(inst.world);
        Builder b;
        const unsigned first = options.split == Split::Nodes ? 0u : k;
        const unsigned last = options.split == Split::Nodes ? inst.node->mNumMeshes : k + 1;
        for (unsigned i = first; i < last; ++i)
          if (const Status st = add_mesh(scene->mMeshes[inst.node->mMeshes[i]], p, source, inst.path, &b, &stats); !st)
            return st;
        if (const Status st = finish(std::move(b), p, std::move(o), &stats, &objects); !st) return st;
      }
    }
  }
  // Meshes no node uses are not part of the model's scene: not imported.
  if (objects.empty()) {
    std::string why = "no triangles found";
    if (stats.points_lines > 0 || stats.degenerate > 0 || stats.empty_meshes > 0)
      why += " (skipped: " + std::to_string(stats.points_lines) + " points or lines, " +
             std::to_string(stats.degenerate) + " degenerate triangles, " + std::to_string(stats.empty_meshes) +
             " empty meshes)";
    return fail(source, why);
  }
  ++stats.files;
  for (ImportedObject& o : objects) out->objects.push_back(std::move(o));
  out->stats.add(stats);
  return Status::Ok();
}

std::string size_text(std::uintmax_t bytes) {
  char buf[64];
  if (bytes >= 1'000'000)
    std::snprintf(buf, sizeof buf, "%.1f MB", static_cast<double>(bytes) / 1e6);
  else
    std::snprintf(buf, sizeof buf, "%.1f kB", static_cast<double>(bytes) / 1e3);
  return buf;
}

/// assimp's progress of reading one file, passed on as "<path>: N% through
/// assimp's reading and post-processing" at most every 2 seconds (nothing
/// for a file read faster).
class ReadProgress : public Assimp::ProgressHandler {
 public:
  ReadProgress(const ImportOptions& options, std::string path) : options_(options), path_(std::move(path)) {}
  bool Update(float fraction) override {
    const auto now = std::chrono::steady_clock::now();
    if (options_.progress && fraction >= 0.0f && now - last_ >= std::chrono::seconds(2)) {
      last_ = now;
      options_.progress(path_ + ": " + std::to_string(static_cast<int>(std::min(fraction, 1.0f) * 100.0f)) +
                        "% through assimp's reading and post-processing");
    }
    return true;  // Never cancels.
  }

 private:
  const ImportOptions& options_;
  std::string path_;
  std::chrono::steady_clock::time_point last_ = std::chrono::steady_clock::now();
};

/// Installs a progress handler and a file system for one read; the importer
/// gives them back (without deleting them: they are the caller's) when the
/// guard goes.
class ProgressGuard {
 public:
  ProgressGuard(Assimp::Importer& importer, Assimp::ProgressHandler* handler, Assimp::IOSystem* files)
      : importer_(importer) {
    importer_.SetProgressHandler(handler);
    importer_.SetIOHandler(files);
  }
  ~ProgressGuard() {
    importer_.SetProgressHandler(nullptr);
    importer_.SetIOHandler(nullptr);
  }
  ProgressGuard(const ProgressGuard&) = delete;
  ProgressGuard& operator=(const ProgressGuard&) = delete;

 private:
  Assimp::Importer& importer_;
};

Status import_one(Assimp::Importer& importer, const std::string& path, const ImportOptions& options,
                  std::vector<bool>* used, ImportResult* out) {
  std::error_code ec;
  const auto status = std::filesystem::status(path, ec);
  if (ec || !std::filesystem::exists(status))
    return fail(path, "cannot open: " + (ec ? ec.message() : std::string("no such file")));
  if (std::filesystem::is_directory(status)) return fail(path, "cannot open: is a directory");
  const auto start = std::chrono::steady_clock::now();
  if (options.progress) options.progress("reading " + path + " (" + size_text(std::filesystem::file_size(path, ec)) + ")");
  ReadProgress read_progress(options, path);
  ModelFolderIO files(path);
  const aiScene* scene = nullptr;
  {
    const ProgressGuard guard(importer, &read_progress, &files);
    scene = importer.ReadFile(path, post_processing());
  }
  if (scene == nullptr && !files.refused().empty()) return fail(path, "cannot import: " + files.refused());
  if (scene == nullptr) {
    // assimp catches an allocation that failed and says so in its error.
    const std::string error = importer.GetErrorString();
    if (error.find("bad_alloc") != std::string::npos) return Status::Exhausted(path, "out of memory while importing");
    return fail(path, "cannot import: " + error);
  }
  const std::size_t before = out->objects.size();
  const ImportStats stats_before = out->stats;
  const Status st = convert(scene, path, options, used, out);
  importer.FreeScene();
  if (!st) return st;
  if (options.progress) {
    const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    char buf[64];
    std::snprintf(buf, sizeof buf, " in %.1f s", secs);
    options.progress(path + ": " + std::to_string(out->objects.size() - before) + (out->objects.size() - before == 1 ? " object, " : " objects, ") +
                     std::to_string(out->stats.triangles - stats_before.triangles) + " triangles" + buf);
  }
  return Status::Ok();
}

Status check_dynamic(const ImportOptions& options, const std::vector<bool>& used, const ImportResult& result) {
  for (std::size_t i = 0; i < options.dynamic_names.size(); ++i) {
    if (used[i]) continue;
    std::string names;
    std::unordered_set<std::string> seen;
    std::size_t shown = 0;
    for (const ImportedObject& o : result.objects) {
      if (!seen.insert(o.name).second) continue;
      if (shown++ == 8) {
        names += ", ...";
        break;
      }
      names += (names.empty() ? "" : ", ") + quote_name(o.name);
    }
    return Status::Error("--dynamic", "no object is named " + quote_name(options.dynamic_names[i]) +
                                          " (object names, node names and node paths are matched; the objects are " +
                                          names + ")");
  }
  return Status::Ok();
}

Status guarded(const std::function<Status()>& body, const std::string& source) {
  try {
    return body();
  } catch (const std::bad_alloc&) {
    return Status::Exhausted(source, "out of memory while importing");
  } catch (const std::exception& e) {
    return fail(source, std::string("cannot import: ") + e.what());
  }
}

}  // namespace

bool parse_split(const std::string& text, Split* out) {
  if (text == "nodes") *out = Split::Nodes;
  else if (text == "meshes") *out = Split::Meshes;
  else if (text == "whole") *out = Split::Whole;
  else return false;
  return true;
}

const char* split_name(Split split) {
  switch (split) {
    case Split::Nodes: return "nodes";
    case Split::Meshes: return "meshes";
    case Split::Whole: return "whole";
  }
  return "?";
}

void ImportStats::add(const ImportStats& o) {
  files += o.files;
  nodes += o.nodes;
  mesh_instances += o.mesh_instances;
  triangles += o.triangles;
  vertices += o.vertices;
  degenerate += o.degenerate;
  points_lines += o.points_lines;
  empty_meshes += o.empty_meshes;
  empty_objects += o.empty_objects;
}

Status import_files(const std::vector<std::string>& paths, const ImportOptions& options, ImportResult* out) {
  if (paths.empty()) return Status::Error("", "no model file given");
  return guarded(
      [&] {
        Assimp::Importer importer;
        configure(importer);
        std::vector<bool> used(options.dynamic_names.size(), false);
        for (const std::string& path : paths)
          if (const Status st = import_one(importer, path, options, &used, out); !st) return st;
        return check_dynamic(options, used, *out);
      },
      paths.front());
}

Status import_memory(const void* data, std::size_t size, const std::string& hint, const std::string& source,
                     const ImportOptions& options, ImportResult* out) {
  return guarded(
      [&] {
        if (size == 0) return fail(source, "cannot import: the file is empty");
        Assimp::Importer importer;
        configure(importer);
        const aiScene* scene = importer.ReadFileFromMemory(data, size, post_processing(), hint.c_str());
        if (scene == nullptr) return fail(source, std::string("cannot import: ") + importer.GetErrorString());
        std::vector<bool> used(options.dynamic_names.size(), false);
        if (const Status st = convert(scene, source, options, &used, out); !st) return st;
        return check_dynamic(options, used, *out);
      },
      source);
}

Status load_model_mesh(const std::string& path, const std::string& name, std::shared_ptr<const Mesh>* out) {
  ImportOptions options;
  options.split = name.empty() ? Split::Whole : Split::Meshes;
  ImportResult result;
  if (const Status st = import_files({path}, options, &result); !st) return st;
  auto mesh = std::make_shared<Mesh>();
  bool any = false;
  for (const ImportedObject& o : result.objects) {
    const std::string node_name = o.node.substr(o.node.find_last_of('/') + 1);
    if (!name.empty() && o.name != name && node_name != name && o.node != name) continue;
    any = true;
    const auto base = static_cast<std::uint32_t>(mesh->vertices.size());
    mesh->vertices.insert(mesh->vertices.end(), o.desc.mesh->vertices.begin(), o.desc.mesh->vertices.end());
    for (auto t : o.desc.mesh->triangles) mesh->triangles.push_back({t[0] + base, t[1] + base, t[2] + base});
  }
  if (!any) return Status::Error(path, "no mesh or node named " + quote_name(name));
  if (const Status st = validate_mesh(*mesh, "mesh"); !st) return Status::Error(path, st.str());
  *out = std::move(mesh);
  return Status::Ok();
}

bool objects_bounds(const std::vector<ImportedObject>& objects, Vec3* lo, Vec3* hi) {
  if (objects.empty()) return false;
  *lo = Vec3(std::numeric_limits<double>::infinity());
  *hi = -*lo;
  for (const ImportedObject& o : objects) {
    Vec3 a, b;
    object_bounds(o.desc, &a, &b);
    *lo = glm::min(*lo, a);
    *hi = glm::max(*hi, b);
  }
  return true;
}

}  // namespace voxvis::import
