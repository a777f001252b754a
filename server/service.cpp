#include "service.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <optional>
#include <utility>

#include "calls.h"
#include "convert.h"
#include "streams.h"

namespace voxvis::server {
namespace {

using Clock = std::chrono::steady_clock;

std::string mib(std::uint64_t bytes) {
  return std::to_string((bytes + (1u << 20) - 1) >> 20) + " MiB";
}

/// An environment variable's value; empty when unset.
std::string env_text(const char* name) {
  const char* v = std::getenv(name);
  return v ? v : "";
}

/// Frames of one scene finish in any order: the statistic keeps the latest.
void store_max(std::atomic<double>& a, double v) {
  double cur = a.load(std::memory_order_relaxed);
  while (cur < v && !a.compare_exchange_weak(cur, v, std::memory_order_relaxed)) {
  }
}

/// Starts a raw unary call: checks the token's role, takes a place among the
/// calls in progress and parses the request. Null after answering the call
/// (UNAUTHENTICATED, PERMISSION_DENIED, RESOURCE_EXHAUSTED, or
/// INVALID_ARGUMENT when the bytes are not a Req); `*reactor` is the call's
/// reactor either way.
template <class Req, class Resp>
TypedUnaryCall<Req, Resp>* start_call(Service* svc, const char* method,
                                      grpc::CallbackServerContext* ctx, Role role,
                                      const grpc::ByteBuffer* in, grpc::ByteBuffer* out,
                                      grpc::ServerUnaryReactor** reactor) {
  auto* call = new TypedUnaryCall<Req, Resp>(out);
  *reactor = call;
  if (grpc::Status denied = svc->tokens().authorize(ctx, role); !denied.ok()) {
    svc->finish_unary(call, method, denied);
    return nullptr;
  }
  if (grpc::Status busy = svc->enter_call(); !busy.ok()) {
    svc->finish_unary(call, method, busy);
    return nullptr;
  }
  call->on_end([svc] { svc->leave_call(); });
  if (parse_message(*in, &call->req)) return call;
  svc->finish_unary(call, method, malformed(Req::descriptor()->full_name(), in->Length()));
  return nullptr;
}

}  // namespace

// ---------------------------------------------------------------------------
// Wake list

void SceneEntry::refresh_wake() {
  std::lock_guard<std::mutex> lock(wake_mu);
  // The epoch is read before the set: a change in between is seen again next
  // time, never lost.
  const std::uint64_t epoch = scene->wake_epoch();
  if (epoch == wake_epoch_seen && wake) return;
  wake_epoch_seen = epoch;
  std::vector<ObjectId> ids = scene->wake_set();
  wake_size.store(static_cast<std::uint32_t>(ids.size()), std::memory_order_relaxed);
  if (metrics) metrics->wake_size(ids.size());
  if (wake && wake->ids == ids) return;
  auto snap = std::make_shared<WakeSnapshot>();
  snap->version = wake ? wake->version + 1 : 1;
  snap->ids = std::move(ids);
  wake = snap;
  for (const auto& sink : sinks) {
    std::lock_guard<std::mutex> sink_lock(sink->mu);
    if (sink->reactor) deliver_wake(sink->reactor, wake);
  }
}

void SceneEntry::after_frame(const FrameResult& result) {
  frames_served.fetch_add(1, std::memory_order_relaxed);
  tbvs_active.store(result.stats.tbvs_active, std::memory_order_relaxed);
  if (metrics) metrics->tbvs_active(result.stats.tbvs_active);
  store_max(time, result.t);
  refresh_wake();
}

void SceneEntry::after_moves(double at) {
  store_max(time, at);
  store_max(sim_time, at);
  sim_clock_set = true;
}

double SceneEntry::view_time(double t, double lead) const {
  return std::fmin(t, sim_time.load(std::memory_order_relaxed) + lead);
}

void SceneEntry::subscribe(const std::shared_ptr<WakeSink>& sink) {
  refresh_wake();
  std::lock_guard<std::mutex> lock(wake_mu);
  sinks.push_back(sink);
  std::lock_guard<std::mutex> sink_lock(sink->mu);
  if (sink->reactor) deliver_wake(sink->reactor, wake);  // The whole list first.
}

void SceneEntry::unsubscribe(const std::shared_ptr<WakeSink>& sink) {
  std::lock_guard<std::mutex> lock(wake_mu);
  sinks.erase(std::remove(sinks.begin(), sinks.end(), sink), sinks.end());
}

// ---------------------------------------------------------------------------
// Service

Service::Service(ServiceConfig config, WorkerPool& pool, WorkerPool& builds, SceneStore& store,
                 const TokenTable& tokens, Metrics& metrics, Log log)
    : config_(std::move(config)),
      pool_(pool),
      builds_(builds),
      store_(store),
      tokens_(tokens),
      metrics_(metrics),
      log_(std::move(log)),
      fail_scene_(env_text("VOXVIS_TEST_FAIL_SCENE")),
      fail_build_(env_text("VOXVIS_TEST_FAIL_BUILD")) {}

Service::~Service() = default;

std::shared_ptr<SceneEntry> Service::find(const std::string& id) const {
  std::lock_guard<std::mutex> lock(scenes_mu_);
  auto it = scenes_.find(id);
  return it == scenes_.end() ? nullptr : it->second;
}

bool Service::has_scene(const std::string& id) const { return find(id) != nullptr; }

bool Service::add_stream(Stream* s) {
  std::lock_guard<std::mutex> lock(streams_mu_);
  if (shutting_down_) return false;
  streams_.insert(s);
  return true;
}

void Service::remove_stream(Stream* s) {
  std::lock_guard<std::mutex> lock(streams_mu_);
  streams_.erase(s);
}

void Service::begin_shutdown() {
  std::lock_guard<std::mutex> lock(streams_mu_);
  shutting_down_ = true;
  stopping_.store(true);
  for (Stream* s : streams_) s->stop_if(nullptr, shutting_down_status());
}

grpc::Status Service::enter_call() {
  if (calls_.fetch_add(1, std::memory_order_relaxed) < config_.max_calls) return grpc::Status::OK;
  calls_.fetch_sub(1, std::memory_order_relaxed);
  return grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED,
                      "server busy: " + std::to_string(config_.max_calls) +
                          " calls in progress (--max-calls); try again");
}

void Service::verify_served(const SceneEntry& e, const std::string& viewer, std::uint64_t frame,
                            const Camera& camera, const FrameResult& result) {
  if (!verifier_ || !e.verify_objects) return;
  std::uint64_t epoch = 0;
  const std::vector<Move> centers = e.scene->dynamic_centers(nullptr, &epoch);
  if (epoch != result.positions_epoch) {
    // A move batch landed between the frame and this read: the positions the
    // frame saw are gone, and checking against newer ones could report
    // misses that were none.
    verifier_->dropped(e.metrics.get());
    return;
  }
  VerifyJob job;
  job.scene = e.id;
  job.viewer = viewer;
  job.frame = frame;
  job.t = result.t;
  job.camera = camera;
  job.pvs = result.pvs;
  job.objects = objects_at(*e.verify_objects, centers);
  job.metrics = e.metrics;
  verifier_->submit(std::move(job));
}

void Service::count_error(const char* method, const grpc::Status& status) {
  metrics_.error(method, status.error_code());
}

void Service::finish_unary(UnaryCall* r, const char* method, const grpc::Status& s) {
  if (!s.ok()) count_error(method, s);
  r->finish(s);
}

std::shared_ptr<SceneEntry> Service::find_or_finish(UnaryCall* r, const char* method,
                                                    const std::string& id) {
  if (grpc::Status s = check_scene_id(id); !s.ok()) {
    finish_unary(r, method, s);
    return nullptr;
  }
  std::shared_ptr<SceneEntry> e = find(id);
  if (!e) finish_unary(r, method, no_scene(id));
  return e;
}

void Service::fill_info(const SceneEntry& e, v1::SceneInfo* out) const {
  out->set_scene_id(e.id);
  out->mutable_grid()->set_nx(static_cast<std::uint32_t>(e.grid.res.x));
  out->mutable_grid()->set_ny(static_cast<std::uint32_t>(e.grid.res.y));
  out->mutable_grid()->set_nz(static_cast<std::uint32_t>(e.grid.res.z));
  vec_to_proto(e.grid.bounds_min, out->mutable_bounds_min());
  vec_to_proto(e.grid.bounds_max, out->mutable_bounds_max());
  out->set_objects(e.objects);
  out->set_dynamic_objects(e.dynamic_objects);
  out->set_time(e.time.load());
  out->set_viewers(e.viewers.load());
  out->set_simulators(e.simulators.load());
  out->set_frames_served(e.frames_served.load());
  out->set_moves_applied(e.moves_applied.load());
  out->set_tbvs_active(e.tbvs_active.load());
  out->set_wake_size(e.wake_size.load());
  out->set_memory_bytes(e.memory_bytes);
}

grpc::Status Service::build_scene(const std::string& id, SceneDesc desc, const std::string& json,
                                  bool from_json, bool persist, const BuildControl* control) {
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
        if (shutting_down()) return shutting_down_status();
        return grpc::Status(grpc::StatusCode::CANCELLED,
                            "scene build stopped: the client went away or its deadline passed");
      default:
        return invalid(scene_create_error(s, from_json, json));
    }
  };
  std::uint64_t available;
  std::string budget_text;
  {
    std::lock_guard<std::mutex> lock(scenes_mu_);
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
  // Each worker's scratch grows to the largest scene it serves: counted
  // for every scene, a figure on the high side, as a budget should be.
  const std::uint64_t bytes = cost.bytes + cost.scratch_bytes * config_.workers;
  {
    std::lock_guard<std::mutex> lock(scenes_mu_);
    if (grpc::Status s = id_free_locked(id); !s.ok()) return s;
    if (bytes_in_use_ + bytes > config_.memory_budget_bytes)
      return grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED,
                          "memory: the scene needs about " + mib(bytes) + " (grid " + std::to_string(cost.res.x) +
                              "x" + std::to_string(cost.res.y) + "x" + std::to_string(cost.res.z) + ", " +
                              std::to_string(cost.id_entries) + " id-list entries, scratch of " +
                              std::to_string(config_.workers) + " workers); memory budget " +
                              mib(config_.memory_budget_bytes) + ", " + mib(bytes_in_use_) + " in use");
    reserved_[id] = bytes;
    bytes_in_use_ += bytes;
  }

  // From here on every way out but the registration below, a throw
  // included, gives the id and the bytes back.
  struct Reservation {
    std::function<void()> release;
    ~Reservation() {
      if (release) release();
    }
  } reservation{[&] {
    std::lock_guard<std::mutex> lock(scenes_mu_);
    reserved_.erase(id);
    bytes_in_use_ -= bytes;
  }};
  auto entry = std::make_shared<SceneEntry>();
  ctl.max_bytes = cost.bytes;
  Status s = Scene::create(desc, opt, &entry->scene, &ctl);
  if (!s) return engine_status(s, budget_text);
  if (!fail_build_.empty() && id == fail_build_) throw std::runtime_error("fault injected (VOXVIS_TEST_FAIL_BUILD)");
  entry->id = id;
  entry->strand = std::make_shared<Strand>(pool_, "scene:" + id);
  entry->memory_bytes = bytes;
  entry->grid = entry->scene->grid();
  entry->objects = static_cast<std::uint32_t>(entry->scene->object_count());
  entry->dynamic_objects = static_cast<std::uint32_t>(entry->scene->dynamic_count());
  entry->time.store(entry->scene->time());
  entry->metrics = metrics_.scene(id);
  if (verifier_) {
    std::vector<ObjectDesc> objects = std::move(desc.objects);
    std::sort(objects.begin(), objects.end(), [](const ObjectDesc& a, const ObjectDesc& b) { return a.id < b.id; });
    entry->verify_objects = std::make_shared<const std::vector<ObjectDesc>>(std::move(objects));
  }
  entry->refresh_wake();
  entry->tbvs_active.store(0);
  // On disk last, so that nothing that can fail comes between the file and
  // the registration.
  if (persist) {
    if (Status w = store_.save_scene(id, json); !w) {
      metrics_.remove_scene(id);
      return grpc::Status(grpc::StatusCode::INTERNAL, "cannot store the scene: " + w.str());
    }
  }
  std::size_t count;
  {
    std::lock_guard<std::mutex> lock(scenes_mu_);
    reservation.release = nullptr;  // The bytes stay, now the scene's.
    reserved_.erase(id);
    scenes_[id] = entry;
    count = scenes_.size();
  }
  metrics_.scenes(count);
  return grpc::Status::OK;
}

grpc::Status Service::id_free_locked(const std::string& id) const {
  if (deleting_.count(id))
    return grpc::Status(grpc::StatusCode::ABORTED, "scene_id: '" + id + "' is being deleted; try again");
  if (scenes_.count(id) || reserved_.count(id))
    return grpc::Status(grpc::StatusCode::ALREADY_EXISTS, "scene_id: '" + id + "' exists");
  return grpc::Status::OK;
}

Status Service::load_scene(const std::string& id, const std::string& json,
                           const std::string& source, const std::vector<Move>* positions,
                           std::optional<double> t, bool persist) {
  SceneDesc desc;
  FormatError err;
  if (!parse_scene(json, source, &desc, &err)) return Status::Error("", err.str());
  // Checked before the scene is registered, so that applying it cannot fail.
  if (t) {
    if (Status s = validate_time("t", *t); !s) return Status::Error("", source + ": saved time: " + s.str());
  }
  if (positions) {
    std::map<ObjectId, Vec3> at;
    for (const Move& m : *positions) at[m.id] = m.center;
    for (ObjectDesc& o : desc.objects) {
      auto it = at.find(o.id);
      if (o.dynamic && it != at.end()) o.center = it->second;
    }
  }
  grpc::Status g = build_scene(id, std::move(desc), json, true, persist);
  if (!g.ok()) return Status::Error("", source + ": " + g.error_message());
  if (t) {
    // Nothing serves the scene yet: the strand's fields are ours here.
    std::shared_ptr<SceneEntry> e = find(id);
    e->scene->apply_moves(*t, {});
    e->time.store(*t);
    e->sim_time.store(*t);
    e->sim_clock_set = true;
  }
  return Status::Ok();
}

void Service::save_positions() {
  std::vector<std::shared_ptr<SceneEntry>> entries;
  {
    std::lock_guard<std::mutex> lock(scenes_mu_);
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

// --- RPCs ------------------------------------------------------------------

grpc::ServerUnaryReactor* Service::CreateScene(grpc::CallbackServerContext* ctx,
                                               const grpc::ByteBuffer* in, grpc::ByteBuffer* out) {
  grpc::ServerUnaryReactor* reactor = nullptr;
  auto* r = start_call<v1::CreateSceneRequest, v1::SceneInfo>(
      this, "CreateScene", ctx, Role::Admin, in, out, &reactor);
  if (!r) return reactor;
  const v1::CreateSceneRequest* req = &r->req;
  v1::SceneInfo* resp = &r->resp;
  if (grpc::Status s = check_scene_id(req->scene_id()); !s.ok()) {
    finish_unary(r, "CreateScene", s);
    return reactor;
  }
  // Parsing and building a grid take long: off the callback thread, and on
  // the build thread, not a frame worker. A build stops when its client has
  // gone, its deadline has passed or the server is stopping.
  builds_.submit(ctx->peer(), [this, ctx, r, req, resp](Scratch&) {
    if (ctx->IsCancelled()) {
      count_dropped();
      r->finish(grpc::Status(grpc::StatusCode::CANCELLED, "cancelled"));
      return;
    }
    if (shutting_down()) {
      count_dropped();
      finish_unary(r, "CreateScene", shutting_down_status());
      return;
    }
    const auto deadline = ctx->deadline();
    BuildControl control;
    control.cancelled = [this, ctx, deadline] {
      return shutting_down() || ctx->IsCancelled() || std::chrono::system_clock::now() > deadline;
    };
    // Everything below may throw (memory exhausted by a huge document, say):
    // then the call ends INTERNAL and the server goes on.
    grpc::Status g;
    try {
      SceneDesc desc;
      std::string json;
      bool from_json = false;
      Status s;
      switch (req->content_case()) {
        case v1::CreateSceneRequest::kDescription:
          s = desc_from_proto(req->description(), &desc);
          if (s) json = scene_to_json(desc);
          break;
        case v1::CreateSceneRequest::kSceneJson:
          from_json = true;
          json = req->scene_json();
          s = desc_from_json(json, &desc);
          break;
        default:
          s = Status::Error("content", "missing: set description or scene_json");
      }
      g = s ? build_scene(req->scene_id(), std::move(desc), json, from_json, true, &control) : invalid(s);
      if (g.ok()) {
        fill_info(*find(req->scene_id()), resp);
        log_("created scene '" + req->scene_id() + "'");
      } else if (g.error_code() == grpc::StatusCode::CANCELLED) {
        log_("build of scene '" + req->scene_id() + "' stopped: its client went away or its deadline passed");
      }
    } catch (const std::exception& e) {
      log_("internal error creating scene '" + req->scene_id() + "': " + e.what());
      g = grpc::Status(grpc::StatusCode::INTERNAL, std::string("internal error creating the scene: ") + e.what());
    }
    finish_unary(r, "CreateScene", g);
  });
  return reactor;
}

grpc::ServerUnaryReactor* Service::DeleteScene(grpc::CallbackServerContext* ctx,
                                               const grpc::ByteBuffer* in, grpc::ByteBuffer* out) {
  grpc::ServerUnaryReactor* reactor = nullptr;
  auto* r = start_call<v1::DeleteSceneRequest, v1::DeleteSceneResponse>(
      this, "DeleteScene", ctx, Role::Admin, in, out, &reactor);
  if (!r) return reactor;
  const v1::DeleteSceneRequest* req = &r->req;
  if (grpc::Status s = check_scene_id(req->scene_id()); !s.ok()) {
    finish_unary(r, "DeleteScene", s);
    return reactor;
  }
  // The id stays taken (deleting_) until the scene's files and metrics are
  // gone, so that a CreateScene of the same id cannot interleave with the
  // removal and lose its files or its metric series.
  std::shared_ptr<SceneEntry> e;
  std::size_t count;
  {
    std::lock_guard<std::mutex> lock(scenes_mu_);
    auto it = scenes_.find(req->scene_id());
    if (it != scenes_.end()) {
      e = it->second;
      scenes_.erase(it);
      bytes_in_use_ -= e->memory_bytes;
      deleting_.insert(e->id);
    }
    count = scenes_.size();
  }
  if (!e) {
    finish_unary(r, "DeleteScene", no_scene(req->scene_id()));
    return reactor;
  }
  Status removed;
  {
    std::lock_guard<std::mutex> lock(store_mu_);
    e->deleted.store(true);
    removed = store_.remove_scene(e->id);
  }
  {
    std::lock_guard<std::mutex> lock(streams_mu_);
    for (Stream* s : streams_)
      s->stop_if(e.get(), deleted(*e));
  }
  metrics_.remove_scene(e->id);
  metrics_.scenes(count);
  {
    std::lock_guard<std::mutex> lock(scenes_mu_);
    deleting_.erase(e->id);
  }
  if (!removed) {
    log_("scene '" + e->id + "' deleted but its files remain: " + removed.str());
    finish_unary(r, "DeleteScene",
                 grpc::Status(grpc::StatusCode::INTERNAL, "cannot remove the scene's files: " + removed.str()));
    return reactor;
  }
  log_("deleted scene '" + e->id + "'");
  finish_unary(r, "DeleteScene", grpc::Status::OK);
  return reactor;
}

grpc::ServerUnaryReactor* Service::ListScenes(grpc::CallbackServerContext* ctx,
                                              const grpc::ByteBuffer* in, grpc::ByteBuffer* out) {
  grpc::ServerUnaryReactor* reactor = nullptr;
  auto* r = start_call<v1::ListScenesRequest, v1::ListScenesResponse>(
      this, "ListScenes", ctx, Role::Viewer, in, out, &reactor);
  if (!r) return reactor;
  v1::ListScenesResponse* resp = &r->resp;
  std::vector<std::shared_ptr<SceneEntry>> entries;
  {
    std::lock_guard<std::mutex> lock(scenes_mu_);
    for (auto& [id, e] : scenes_) entries.push_back(e);
  }
  for (const auto& e : entries) fill_info(*e, resp->add_scenes());
  finish_unary(r, "ListScenes", grpc::Status::OK);
  return reactor;
}

grpc::ServerUnaryReactor* Service::GetSceneStats(grpc::CallbackServerContext* ctx,
                                                 const grpc::ByteBuffer* in, grpc::ByteBuffer* out) {
  grpc::ServerUnaryReactor* reactor = nullptr;
  auto* r = start_call<v1::GetSceneStatsRequest, v1::SceneInfo>(
      this, "GetSceneStats", ctx, Role::Viewer, in, out, &reactor);
  if (!r) return reactor;
  const v1::GetSceneStatsRequest* req = &r->req;
  v1::SceneInfo* resp = &r->resp;
  std::shared_ptr<SceneEntry> e = find_or_finish(r, "GetSceneStats", req->scene_id());
  if (!e) return reactor;
  fill_info(*e, resp);
  finish_unary(r, "GetSceneStats", grpc::Status::OK);
  return reactor;
}

grpc::ServerUnaryReactor* Service::GetPvs(grpc::CallbackServerContext* ctx,
                                          const grpc::ByteBuffer* in, grpc::ByteBuffer* out) {
  grpc::ServerUnaryReactor* reactor = nullptr;
  auto* r = start_call<v1::GetPvsRequest, v1::GetPvsResponse>(
      this, "GetPvs", ctx, Role::Viewer, in, out, &reactor);
  if (!r) return reactor;
  const v1::GetPvsRequest* req = &r->req;
  v1::GetPvsResponse* resp = &r->resp;
  std::shared_ptr<SceneEntry> e = find_or_finish(r, "GetPvs", req->scene_id());
  if (!e) return reactor;
  Camera camera;
  if (Status s = camera_from_proto(req->camera(), req->has_camera(), &camera); !s) {
    finish_unary(r, "GetPvs", invalid(s));
    return reactor;
  }
  if (Status s = validate_time("t", req->t()); !s) {
    finish_unary(r, "GetPvs", invalid(s));
    return reactor;
  }
  const Clock::time_point received = Clock::now();
  pool_.submit(ctx->peer(), [this, ctx, r, e, camera, t = req->t(), resp, received](Scratch& scratch) {
    // Work nobody waits for any more is answered without running.
    if (ctx->IsCancelled()) {
      count_dropped();
      r->finish(grpc::Status(grpc::StatusCode::CANCELLED, "cancelled"));
      return;
    }
    if (shutting_down()) {
      count_dropped();
      finish_unary(r, "GetPvs", shutting_down_status());
      return;
    }
    if (e->deleted.load()) {
      finish_unary(r, "GetPvs", deleted(*e));
      return;
    }
    Scene& scene = *e->scene;
    FrameResult result;
    grpc::Status g = guarded(*e, "frame", [&] {
      // A one-frame viewer, removed however the frame ends.
      struct OneFrameViewer {
        Scene& scene;
        const ViewerId id = scene.add_viewer();
        ~OneFrameViewer() { scene.remove_viewer(id); }
      } viewer{scene};
      Status s = scene.frame(viewer.id, camera, e->view_time(t, config_.max_view_lead_s), scratch, &result,
                             Scene::Clock::Latest);
      return s ? grpc::Status::OK : invalid(s);
    });
    if (!g.ok()) {
      finish_unary(r, "GetPvs", g);
      return;
    }
    e->after_frame(result);
    add_ids(result.pvs, resp->mutable_pvs());
    stats_to_proto(result.stats, resp->mutable_stats());
    resp->set_t(result.t);
    if (e->metrics)
      e->metrics->frame(result.stats, std::chrono::duration<double>(Clock::now() - received).count());
    const bool check = verify_sample();
    const std::string peer = check ? ctx->peer() : std::string();
    finish_unary(r, "GetPvs", grpc::Status::OK);
    if (check) verify_served(*e, peer + " (GetPvs)", 0, camera, result);
  });
  return reactor;
}

grpc::Status Service::apply_batch(SceneEntry& e, double t, const std::vector<Move>& moves,
                                  const std::string& field_prefix, MoveReport* report) {
  // One batch may advance the clock by a bounded step; the first one on a
  // scene adopts the backend's epoch.
  const double step_limit = config_.max_time_step_s;
  const double from = e.sim_time.load(std::memory_order_relaxed);
  if (e.sim_clock_set && t - from > step_limit)
    return invalid(Status::Error(field_prefix + "t", number_text(t) + " is " + number_text(t - from) +
                                                       " s beyond the scene's clock (" + number_text(from) +
                                                       "); one batch may advance it by at most " +
                                                       number_text(step_limit) + " s"));
  Scene& scene = *e.scene;
  const grpc::Status g = guarded(e, "move batch", [&] {
    Status s = scene.apply_moves(t, moves, report, Scene::Clock::Latest);
    return s ? grpc::Status::OK : invalid(Status::Error(field_prefix + s.field, s.message));
  });
  if (!g.ok()) return g;
  e.moves_applied.fetch_add(report->applied, std::memory_order_relaxed);
  e.after_moves(report->t);
  if (report->applied) e.positions_dirty.store(true, std::memory_order_relaxed);
  if (e.metrics) e.metrics->moves(report->applied);
  e.refresh_wake();
  return grpc::Status::OK;
}

grpc::ServerBidiReactor<grpc::ByteBuffer, grpc::ByteBuffer>* Service::View(
    grpc::CallbackServerContext* ctx) {
  return new_view_stream(this, ctx);
}

grpc::ServerBidiReactor<grpc::ByteBuffer, grpc::ByteBuffer>* Service::Simulate(
    grpc::CallbackServerContext* ctx) {
  return new_simulate_stream(this, ctx);
}

grpc::ServerBidiReactor<grpc::ByteBuffer, grpc::ByteBuffer>* Service::Tick(grpc::CallbackServerContext* ctx) {
  return new_tick_stream(this, ctx);
}

}  // namespace voxvis::server
