#include "wire/convert.h"

#include <algorithm>

#include <cmath>
#include <cstdio>
#include <string_view>
#include <unordered_map>

#include "voxvis/mesh.h"

namespace voxvis::server {

namespace {

Status vec_check(const v1::Vec3& v, const std::string& field, Vec3* out) {
  *out = Vec3(v.x(), v.y(), v.z());
  if (!std::isfinite(out->x) || !std::isfinite(out->y) || !std::isfinite(out->z))
    return Status::Error(field, "must be three finite numbers");
  if (std::fmax(std::fabs(out->x), std::fmax(std::fabs(out->y), std::fabs(out->z))) > kMaxCoordinate)
    return Status::Error(field, "magnitude must be at most " + number_text(kMaxCoordinate));
  return Status::Ok();
}

Status vec_required(bool present, const v1::Vec3& v, const std::string& field, Vec3* out) {
  if (!present) return Status::Error(field, "missing");
  return vec_check(v, field, out);
}

/// The bytes of a vector's elements, for hashing and comparing them as
/// stored (bit for bit: 0.0 and -0.0 differ).
template <class T>
std::string_view bytes_of(const std::vector<T>& v) {
  return std::string_view(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(T));
}

}  // namespace

Status quat_from_proto(const v1::Quat& in, const std::string& field, Quat* out) {
  *out = Quat(in.w(), in.x(), in.y(), in.z());
  return validate_rotation(*out, field);
}

Status mesh_from_proto(const v1::Mesh& in, const std::string& field, std::shared_ptr<const Mesh>* out) {
  const auto nv = static_cast<std::size_t>(in.vertices_size());
  const auto nt = static_cast<std::size_t>(in.triangles_size());
  if (nv % 3 != 0)
    return Status::Error(field + ".vertices", std::to_string(nv) +
                                                  " numbers, not a multiple of 3 (x, y, z of each vertex in turn)");
  if (nt % 3 != 0)
    return Status::Error(field + ".triangles",
                         std::to_string(nt) + " indices, not a multiple of 3 (i, j, k of each triangle in turn)");
  auto mesh = std::make_shared<Mesh>();
  mesh->vertices.resize(nv / 3);
  for (std::size_t i = 0; i < nv / 3; ++i) {
    const int k = static_cast<int>(3 * i);
    mesh->vertices[i] = Vec3(in.vertices(k), in.vertices(k + 1), in.vertices(k + 2));
  }
  mesh->triangles.resize(nt / 3);
  for (std::size_t t = 0; t < nt / 3; ++t) {
    const int k = static_cast<int>(3 * t);
    mesh->triangles[t] = {in.triangles(k), in.triangles(k + 1), in.triangles(k + 2)};
  }
  if (Status s = validate_mesh(*mesh, field); !s) return s;
  *out = std::move(mesh);
  return Status::Ok();
}

void share_identical_meshes(SceneDesc* desc) {
  std::unordered_map<std::size_t, std::vector<std::shared_ptr<const Mesh>>> seen;
  const std::hash<std::string_view> hash;
  for (ObjectDesc& o : desc->objects) {
    if (!o.mesh) continue;
    const std::string_view v = bytes_of(o.mesh->vertices), t = bytes_of(o.mesh->triangles);
    std::vector<std::shared_ptr<const Mesh>>& same_hash = seen[hash(v) * 31 + hash(t)];
    bool shared = false;
    for (const std::shared_ptr<const Mesh>& m : same_hash) {
      if (m == o.mesh || (bytes_of(m->vertices) == v && bytes_of(m->triangles) == t)) {
        o.mesh = m;
        shared = true;
        break;
      }
    }
    if (!shared) same_hash.push_back(o.mesh);
  }
}

Status desc_from_proto(const v1::SceneDescription& in, SceneDesc* out) {
  *out = SceneDesc{};
  const std::string p = "description.";
  if (Status s = vec_required(in.has_bounds_min(), in.bounds_min(), p + "bounds_min", &out->bounds_min); !s)
    return s;
  if (Status s = vec_required(in.has_bounds_max(), in.bounds_max(), p + "bounds_max", &out->bounds_max); !s)
    return s;
  for (int a = 0; a < 3; ++a)
    if (!(out->bounds_min[a] < out->bounds_max[a]))
      return Status::Error(p + "bounds_max", "must be > bounds_min on every axis");
  if (in.has_grid()) {
    const std::uint32_t g[3] = {in.grid().nx(), in.grid().ny(), in.grid().nz()};
    const char* names[3] = {"nx", "ny", "nz"};
    for (int a = 0; a < 3; ++a)
      if (g[a] < 1 || g[a] > kMaxResolution)
        return Status::Error(p + "grid." + names[a], "must be in [1, " + std::to_string(kMaxResolution) +
                                                         "], got " + std::to_string(g[a]));
    out->grid = glm::ivec3(static_cast<int>(g[0]), static_cast<int>(g[1]), static_cast<int>(g[2]));
  }
  // The mesh table first: every entry checked once, named by its index.
  std::vector<std::shared_ptr<const Mesh>> meshes(static_cast<std::size_t>(in.meshes_size()));
  for (int k = 0; k < in.meshes_size(); ++k)
    if (Status s = mesh_from_proto(in.meshes(k), p + "meshes[" + std::to_string(k) + "]",
                                   &meshes[static_cast<std::size_t>(k)]);
        !s)
      return s;
  out->objects.reserve(static_cast<std::size_t>(in.objects_size()));
  // Each table mesh is checked once, and each placement of it in O(1): a
  // description that places a large mesh many times costs its size, not
  // its instances times the mesh.
  MeshPlacementCheck placements;
  for (int i = 0; i < in.objects_size(); ++i) {
    const v1::Object& o = in.objects(i);
    const std::string f = p + "objects[" + std::to_string(i) + "]";
    ObjectDesc d;
    d.id = o.id();
    d.dynamic = o.dynamic();
    switch (o.shape_case()) {
      case v1::Object::kSphere: {
        d.shape = Shape::Sphere;
        if (Status s = vec_required(o.sphere().has_center(), o.sphere().center(), f + ".center", &d.center); !s)
          return s;
        d.radius = o.sphere().radius();
        if (!std::isfinite(d.radius) || !(d.radius > 0.0))
          return Status::Error(f + ".radius", "must be > 0, got " + number_text(d.radius));
        if (d.radius > kMaxCoordinate)
          return Status::Error(f + ".radius", "must be at most " + number_text(kMaxCoordinate));
        break;
      }
      case v1::Object::kBox: {
        d.shape = Shape::Box;
        Vec3 lo, hi;
        if (Status s = vec_required(o.box().has_min(), o.box().min(), f + ".min", &lo); !s) return s;
        if (Status s = vec_required(o.box().has_max(), o.box().max(), f + ".max", &hi); !s) return s;
        for (int a = 0; a < 3; ++a)
          if (!(lo[a] <= hi[a])) return Status::Error(f + ".max", "must be >= min on every axis");
        set_box_corners(lo, hi, &d);
        break;
      }
      case v1::Object::kMesh: {
        // The placement's rules are validate_mesh_object's (voxvis/mesh.h),
        // whose fields (".mesh.center", ".mesh.rotation", ".mesh.scale")
        // are this message's.
        const v1::MeshInstance& m = o.mesh();
        d.shape = Shape::Mesh;
        if (m.index() >= meshes.size())
          return Status::Error(f + ".mesh.index", "mesh " + std::to_string(m.index()) +
                                                      " is out of range (the description has " +
                                                      std::to_string(meshes.size()) +
                                                      (meshes.size() == 1 ? " mesh)" : " meshes)"));
        d.mesh = meshes[m.index()];
        if (m.has_center()) d.center = Vec3(m.center().x(), m.center().y(), m.center().z());
        if (m.has_rotation()) d.rotation = Quat(m.rotation().w(), m.rotation().x(), m.rotation().y(), m.rotation().z());
        if (m.has_scale()) d.scale = m.scale();
        if (Status s = placements.check(d, f + ".mesh"); !s) return s;
        break;
      }
      default:
        return Status::Error(f, "no shape: set sphere, box or mesh");
    }
    const double speed = o.max_speed();
    if (d.dynamic) {
      if (!o.has_max_speed())
        return Status::Error(f + ".max_speed",
                             "dynamic objects need max_speed (world units per second)");
      if (!std::isfinite(speed) || !(speed >= 0.0))
        return Status::Error(f + ".max_speed", "must be >= 0, got " + number_text(speed));
      if (speed > kMaxCoordinate) return Status::Error(f + ".max_speed", "must be at most " + number_text(kMaxCoordinate));
      d.max_speed = speed;
    } else if (speed != 0.0) {
      return Status::Error(f + ".max_speed", "only dynamic objects have a max_speed");
    }
    out->objects.push_back(d);
  }
  return Status::Ok();
}

Status desc_from_json(const std::string& text, SceneDesc* out) {
  FormatError err;
  if (!parse_scene(text, "scene_json", out, &err)) return Status::Error("", err.str());
  share_identical_meshes(out);
  return Status::Ok();
}

Status scene_create_error(const Status& engine, bool from_json, const std::string& json) {
  if (!from_json) return Status::Error("description." + engine.field, engine.message);
  FormatError e{"scene_json", scene_field_line(json, engine.field), engine.field, engine.message};
  return Status::Error("", e.str());
}

Status camera_from_proto(const v1::Camera& in, bool present, Camera* out) {
  if (!present) return Status::Error("camera", "missing");
  const auto vec = [](const v1::Vec3& v) { return Vec3(v.x(), v.y(), v.z()); };
  if (!in.has_eye()) return Status::Error("camera.eye", "missing");
  if (!in.has_dir()) return Status::Error("camera.dir", "missing");
  if (!in.has_up()) return Status::Error("camera.up", "missing");
  out->eye = vec(in.eye());
  out->dir = vec(in.dir());
  out->up = vec(in.up());
  out->fov_y_deg = in.fov_y_deg();
  out->aspect = in.aspect();
  out->near = in.near();
  out->far = in.far();
  out->eye_extent = in.has_eye_extent() ? vec(in.eye_extent()) : Vec3(0.0);
  out->omnidirectional = in.omnidirectional();
  out->horizon_s = in.horizon_s();
  Status s = validate_camera(*out);
  if (!s) return Status::Error("camera." + s.field, s.message);
  return s;
}

Status moves_from_proto(const v1::MoveBatch& in, std::vector<Move>* out) {
  return moves_from_proto(in.moves(), "batch.moves", out);
}

Status moves_from_proto(const google::protobuf::RepeatedPtrField<v1::Move>& in, const std::string& path,
                        std::vector<Move>* out) {
  out->clear();
  out->reserve(static_cast<std::size_t>(in.size()));
  // The first move whose id an earlier move has, by sorting (id, index) in
  // this thread's reused buffer; field names are made only for an error, so
  // a good batch allocates nothing beyond `out`.
  thread_local std::vector<std::pair<ObjectId, int>> ids;
  ids.clear();
  for (int i = 0; i < in.size(); ++i) ids.emplace_back(in.Get(i).id(), i);
  std::sort(ids.begin(), ids.end());
  int twice = in.size();  // Index of the first repeated id; none when in.size().
  for (std::size_t k = 1; k < ids.size(); ++k)
    if (ids[k].first == ids[k - 1].first) twice = std::min(twice, ids[k].second);
  const auto field = [&](int i, const std::string& rest) { return path + "[" + std::to_string(i) + "]." + rest; };
  for (int i = 0; i < in.size(); ++i) {
    const v1::Move& m = in.Get(i);
    if (i == twice)
      return Status::Error(field(i, "id"), "object " + std::to_string(m.id()) + " appears twice in one batch");
    Move mv;
    mv.id = m.id();
    if (Status s = vec_required(m.has_center(), m.center(), "center", &mv.center); !s)
      return Status::Error(field(i, s.field), s.message);
    if (m.has_rotation()) {
      if (Status s = quat_from_proto(m.rotation(), "rotation", &mv.rotation); !s)
        return Status::Error(field(i, s.field), s.message);
      mv.has_rotation = true;
    }
    out->push_back(mv);
  }
  return Status::Ok();
}

void vec_to_proto(const Vec3& in, v1::Vec3* out) {
  out->set_x(in.x);
  out->set_y(in.y);
  out->set_z(in.z);
}

void stats_to_proto(const FrameStats& in, v1::FrameStats* out) {
  out->set_time_us(in.time_us);
  out->set_voxels_visited(in.voxels_visited);
  out->set_shells(in.shells);
  out->set_objects_discretized(in.objects_discretized);
  out->set_tbvs_created(in.tbvs_created);
  out->set_tbvs_revealed(in.tbvs_revealed);
  out->set_tbvs_expired(in.tbvs_expired);
  out->set_tbvs_active(in.tbvs_active);
  out->set_speed_violations(in.speed_violations);
  out->set_outside_tested(in.outside_tested);
  out->set_pvs_size(in.pvs_size);
  out->set_early_exit(in.early_exit);
  out->set_front_voxels_culled(in.front_voxels_culled);
  out->set_front_objects_culled(in.front_objects_culled);
  out->set_ob_width(in.ob_width);
  out->set_ob_voxels_culled(in.ob_voxels_culled);
  out->set_ob_objects_culled(in.ob_objects_culled);
  out->set_ob_occluders(in.ob_occluders);
  out->set_frustum_fallback(in.frustum_fallback);
  out->set_region(in.region);
  out->set_ob_pixels_written(in.ob_pixels_written);
  out->set_cells_visited(in.cells_visited);
  out->set_cells_hidden(in.cells_hidden);
  out->set_cells_whole(in.cells_whole);
  out->set_traverse_us(in.traverse_us);
  out->set_render_us(in.render_us);
  out->set_retest_us(in.retest_us);
}

}  // namespace voxvis::server
