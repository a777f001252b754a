#include "scenes/scene_registry.h"

#include <algorithm>
#include <set>
#include <stdexcept>
#include <utility>

#include "scenes/env.h"
#include "voxvis/format.h"
#include "voxvis/mesh.h"
#include "wire/calls.h"
#include "wire/convert.h"

namespace voxvis::server {
namespace {

std::string mib(std::uint64_t bytes) {
  return std::to_string((bytes + (1u << 20) - 1) >> 20) + " MiB";
}

}  // namespace

SceneRegistry::SceneRegistry(RegistryConfig config, WorkerPool& pool, SceneStore& store, Metrics& metrics, Log log,
                             const std::atomic<bool>& stopping)
    : config_(std::move(config)),
      pool_(pool),
      store_(store),
      metrics_(metrics),
      log_(std::move(log)),
      stopping_(stopping),
      fail_build_(env_text("VOXVIS_TEST_FAIL_BUILD")) {}

std::shared_ptr<SceneEntry> SceneRegistry::find(const std::string& id) const {
  std::lock_guard<std::mutex> lock(mu_);
  auto it = scenes_.find(id);
  return it == scenes_.end() ? nullptr : it->second;
}

std::vector<std::shared_ptr<SceneEntry>> SceneRegistry::list() const {
  std::vector<std::shared_ptr<SceneEntry>> entries;
  std::lock_guard<std::mutex> lock(mu_);
  for (auto& [id, e] : scenes_) entries.push_back(e);
  return entries;
}

grpc::Status SceneRegistry::id_free_locked(const std::string& id) const {
  if (deleting_.count(id))
    return grpc::Status(grpc::StatusCode::ABORTED, "scene_id: '" + id + "' is being deleted; try again");
  if (scenes_.count(id) || reserved_.count(id))
    return grpc::Status(grpc::StatusCode::ALREADY_EXISTS, "scene_id: '" + id + "' exists");
  return grpc::Status::OK;
}

Status place_dynamic(SceneDesc* desc, const std::vector<Move>& moves, bool strict, const std::string& field) {
  // Ids are unique (moves_from_proto refuses a repeated one; a positions
  // file is written from one map): the first of a repeated id would win.
  std::map<ObjectId, std::size_t> at;
  for (std::size_t i = 0; i < moves.size(); ++i) at.emplace(moves[i].id, i);
  std::size_t placed = 0;
  MeshPlacementCheck meshes;
  for (ObjectDesc& o : desc->objects) {
    auto it = at.find(o.id);
    if (it == at.end()) continue;
    const Move& m = moves[it->second];
    const std::string where = field + "[" + std::to_string(it->second) + "]";
    if (!o.dynamic) {
      if (strict) return Status::Error(where + ".id", "object " + std::to_string(o.id) + " is not dynamic");
      continue;
    }
    if (m.has_rotation && o.shape != Shape::Mesh) {
      if (strict)
        return Status::Error(where + ".rotation", "object " + std::to_string(o.id) + " is not a mesh; only meshes rotate");
      continue;
    }
    o.center = m.center;
    if (m.has_rotation) o.rotation = m.rotation;
    if (strict && o.shape == Shape::Mesh) {
      // The move places the mesh: its errors are the move's (the centre,
      // or the rotation that turns the mesh's box beyond the limit).
      if (Status s = meshes.check(o, where); !s) {
        const bool center = s.field == where + ".center" || !m.has_rotation;
        return Status::Error(where + (center ? ".center" : ".rotation"), s.message);
      }
    }
    ++placed;
  }
  if (strict && placed != at.size()) {
    for (std::size_t i = 0; i < moves.size(); ++i) {
      const bool known = std::any_of(desc->objects.begin(), desc->objects.end(),
                                     [&](const ObjectDesc& o) { return o.id == moves[i].id; });
      if (!known)
        return Status::Error(field + "[" + std::to_string(i) + "].id",
                             "no object " + std::to_string(moves[i].id) + " in the scene");
    }
  }
  return Status::Ok();
}

grpc::Status SceneRegistry::create(const std::string& id, SceneDesc desc, const std::string& json, bool from_json,
                                   bool persist, const BuildControl* control, const StartPositions* start) {
  const SceneOptions& opt = config_.scene_options;
  if (desc.grid) {
    // A grid over the voxel limit is refused as too large, not as wrong.
    const glm::ivec3 g = *desc.grid;
    const std::int64_t voxels = std::int64_t{g.x} * g.y * g.z;
    if (g.x > 0 && g.y > 0 && g.z > 0 && voxels > opt.max_voxels)
      return grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED,
                          "grid: " + std::to_string(voxels) + " voxels exceed the limit of " +
                              std::to_string(opt.max_voxels));
  }
  // What the engine returns, as the call's status. `budget`: what the
  // refusal says of the server's budget.
  auto engine_status = [&](const Status& s, const std::string& budget) {
    switch (s.code) {
      case Status::Code::ResourceExhausted:
        return grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED, s.str() + budget);
      case Status::Code::Cancelled:
        if (stopping_.load(std::memory_order_relaxed)) return shutting_down_status();
        return grpc::Status(grpc::StatusCode::CANCELLED,
                            "scene build stopped: the client went away or its deadline passed");
      default:
        return invalid(scene_create_error(s, from_json, json));
    }
  };
  std::uint64_t available;
  std::string budget_text;
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (grpc::Status s = id_free_locked(id); !s.ok()) return s;
    available = config_.memory_budget_bytes > bytes_in_use_ ? config_.memory_budget_bytes - bytes_in_use_ : 0;
    budget_text = "; memory budget " + mib(config_.memory_budget_bytes) + ", " + mib(bytes_in_use_) + " in use";
  }
  // The cost from the objects' footprints, before anything large is
  // allocated; the count stops as soon as it passes what is left.
  BuildControl ctl = control ? *control : BuildControl{};
  ctl.max_bytes = std::max<std::uint64_t>(available, 1);
  SceneCost cost;
  if (Status s = Scene::estimate(desc, opt, &cost, &ctl); !s) return engine_status(s, budget_text);
  const std::uint64_t bytes = cost.served_bytes(config_.workers);
  // While it builds, the scene takes its temporaries too, and its text (as
  // saved) is held.
  const std::uint64_t building = bytes + cost.build_bytes + json.size();
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (grpc::Status s = id_free_locked(id); !s.ok()) return s;
    if (bytes_in_use_ + building > config_.memory_budget_bytes)
      return grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED,
                          "memory: the scene needs about " + mib(building) + " (grid " + std::to_string(cost.res.x) +
                              "x" + std::to_string(cost.res.y) + "x" + std::to_string(cost.res.z) + ", " +
                              std::to_string(cost.id_entries) + " id-list entries, scratch of " +
                              std::to_string(config_.workers) + " workers" +
                              (cost.build_bytes > bytes / 4 ? ", " + mib(cost.build_bytes) + " of it while it builds"
                                                            : std::string()) +
                              "); memory budget " + mib(config_.memory_budget_bytes) + ", " + mib(bytes_in_use_) +
                              " in use");
    reserved_[id] = building;
    bytes_in_use_ += building;
  }

  // From here on every way out but the registration below, a throw
  // included, gives the id and the bytes reserved back.
  struct Reservation {
    std::function<void()> release;
    ~Reservation() {
      if (release) release();
    }
  } reservation{[&] {
    std::lock_guard<std::mutex> lock(mu_);
    bytes_in_use_ -= reserved_[id];
    reserved_.erase(id);
  }};
  auto entry = std::make_shared<SceneEntry>();
  // The build counts what it allocates against its estimate; past it, more
  // is reserved while the budget has room, else the build stops.
  ctl.max_bytes = cost.bytes + cost.build_bytes;
  ctl.reserve = [this, &id, granted = ctl.max_bytes](std::uint64_t needed) mutable {
    std::lock_guard<std::mutex> lock(mu_);
    const std::uint64_t more = needed > granted ? needed - granted : 0;
    if (bytes_in_use_ + more > config_.memory_budget_bytes) return false;
    reserved_[id] += more;
    bytes_in_use_ += more;
    granted = needed;
    return true;
  };
  Status s = Scene::create(desc, opt, &entry->scene, &ctl);
  if (!s) return engine_status(s, budget_text);
  if (!fail_build_.empty() && id == fail_build_) throw std::runtime_error("fault injected (VOXVIS_TEST_FAIL_BUILD)");
  // What the scene keeps: its estimate, or what its build counted when
  // that was more.
  const std::uint64_t kept = std::max(cost.bytes, entry->scene->built_bytes()) + cost.scratch_bytes * config_.workers;
  entry->id = id;
  entry->strand = std::make_shared<Strand>(pool_, "scene:" + id);
  entry->memory_bytes = kept;
  entry->grid = entry->scene->grid();
  entry->objects = static_cast<std::uint32_t>(entry->scene->object_count());
  entry->dynamic_objects = static_cast<std::uint32_t>(entry->scene->dynamic_count());
  {
    std::set<const Mesh*> meshes;
    for (const ObjectDesc& o : desc.objects) {
      if (o.shape != Shape::Mesh) continue;
      ++entry->mesh_objects;
      if (o.mesh && meshes.insert(o.mesh.get()).second) entry->mesh_triangles += o.mesh->triangles.size();
    }
  }
  entry->time.store(entry->scene->time());
  entry->metrics = metrics_.scene(id);
  if (keep_objects_.load()) {
    std::vector<ObjectDesc> objects = std::move(desc.objects);
    std::sort(objects.begin(), objects.end(), [](const ObjectDesc& a, const ObjectDesc& b) { return a.id < b.id; });
    entry->verify_objects = std::make_shared<const std::vector<ObjectDesc>>(std::move(objects));
  }
  if (start) {
    // Nothing serves the scene yet: the strand's fields are ours here.
    entry->scene->apply_moves(start->t, {});
    entry->time.store(start->t);
    entry->sim_time.store(start->t);
    entry->sim_clock_set = true;
  }
  entry->refresh_wake();
  entry->tbvs_active.store(0);
  // On disk last, so that nothing that can fail comes between the file and
  // the registration.
  if (persist) {
    Status w = store_.save_scene(id, json);
    if (w && start && entry->dynamic_objects > 0) w = store_.save_positions(id, start->t, start->moves);
    if (!w) {
      if (Status r = store_.remove_scene(id); !r) log_("cannot remove the files of scene '" + id + "': " + r.str());
      metrics_.remove_scene(id);
      return grpc::Status(grpc::StatusCode::INTERNAL, "cannot store the scene: " + w.str());
    }
  }
  std::size_t count;
  {
    std::lock_guard<std::mutex> lock(mu_);
    reservation.release = nullptr;  // What the scene keeps stays, now the scene's.
    bytes_in_use_ = bytes_in_use_ - reserved_[id] + kept;
    reserved_.erase(id);
    scenes_[id] = entry;
    count = scenes_.size();
  }
  metrics_.scenes(count);
  return grpc::Status::OK;
}

Status SceneRegistry::load(const std::string& id, const std::string& json, const std::string& source,
                           const std::vector<Move>* positions, std::optional<double> t, bool persist) {
  SceneDesc desc;
  FormatError err;
  if (!parse_scene(json, source, &desc, &err)) return Status::Error("", err.str());
  // The file holds every object's mesh inline: instances share it again.
  share_identical_meshes(&desc);
  // Checked before the scene is registered, so that applying it cannot fail.
  if (t) {
    if (Status s = validate_time("t", *t); !s) return Status::Error("", source + ": saved time: " + s.str());
  }
  if (positions) place_dynamic(&desc, *positions, false, "positions");
  StartPositions start;
  if (t) start.t = *t;
  grpc::Status g = create(id, std::move(desc), json, true, persist, nullptr, t ? &start : nullptr);
  if (!g.ok()) return Status::Error("", source + ": " + g.error_message());
  return Status::Ok();
}

grpc::Status SceneRegistry::remove(const std::string& id, const std::function<void(SceneEntry&)>& end_streams) {
  // The id stays taken (deleting_) until the scene's files and metrics are
  // gone, so that a create of the same id cannot interleave with the
  // removal and lose its files or its metric series.
  std::shared_ptr<SceneEntry> e;
  std::size_t count;
  {
    std::lock_guard<std::mutex> lock(mu_);
    auto it = scenes_.find(id);
    if (it != scenes_.end()) {
      e = it->second;
      scenes_.erase(it);
      bytes_in_use_ -= e->memory_bytes;
      deleting_.insert(e->id);
    }
    count = scenes_.size();
  }
  if (!e) return no_scene(id);
  Status removed;
  {
    std::lock_guard<std::mutex> lock(store_mu_);
    e->deleted.store(true);
    removed = store_.remove_scene(e->id);
  }
  end_streams(*e);
  metrics_.remove_scene(e->id);
  metrics_.scenes(count);
  {
    std::lock_guard<std::mutex> lock(mu_);
    deleting_.erase(e->id);
  }
  if (!removed) {
    log_("scene '" + e->id + "' deleted but its files remain: " + removed.str());
    return grpc::Status(grpc::StatusCode::INTERNAL, "cannot remove the scene's files: " + removed.str());
  }
  log_("deleted scene '" + e->id + "'");
  return grpc::Status::OK;
}

void SceneRegistry::save_positions() {
  std::vector<std::shared_ptr<SceneEntry>> entries;
  {
    std::lock_guard<std::mutex> lock(mu_);
    for (auto& [id, e] : scenes_)
      if (e->dynamic_objects > 0 && e->positions_dirty.load()) entries.push_back(e);
  }
  for (const auto& e : entries) {
    e->positions_dirty.store(false);
    double t = 0.0;
    const std::vector<Move> centers = e->scene->dynamic_centers(&t);
    std::lock_guard<std::mutex> lock(store_mu_);
    if (e->deleted.load()) continue;
    if (Status s = store_.save_positions(e->id, t, centers); !s) {
      e->positions_dirty.store(true);  // Try again next period.
      log_("cannot save positions of scene '" + e->id + "': " + s.str());
    }
  }
}

void SceneRegistry::add_misplaced(const std::string& id, const std::string& owner) {
  std::lock_guard<std::mutex> lock(misplaced_mu_);
  misplaced_[id] = owner;
}

std::map<std::string, std::string> SceneRegistry::misplaced() const {
  std::lock_guard<std::mutex> lock(misplaced_mu_);
  return misplaced_;
}

bool SceneRegistry::is_misplaced(const std::string& id) const {
  std::lock_guard<std::mutex> lock(misplaced_mu_);
  return misplaced_.count(id) > 0;
}

grpc::Status SceneRegistry::remove_misplaced(const std::string& id) {
  std::lock_guard<std::mutex> lock(misplaced_mu_);
  if (!misplaced_.count(id)) return grpc::Status(grpc::StatusCode::NOT_FOUND, "not kept");
  if (Status rm = store_.remove_scene(id); !rm)
    return grpc::Status(grpc::StatusCode::INTERNAL, "cannot remove the scene's files: " + rm.str());
  misplaced_.erase(id);
  log_("deleted scene '" + id + "' (kept for another shard)");
  return grpc::Status::OK;
}

}  // namespace voxvis::server
