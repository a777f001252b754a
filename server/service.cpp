#include "service.h"

#include <chrono>
#include <exception>
#include <memory>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include "calls.h"
#include "convert.h"
#include "env.h"
#include "frame_answer.h"
#include "streams.h"
#include "voxvis/assert.h"

namespace voxvis::server {
namespace {

using Clock = std::chrono::steady_clock;

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

/// RESOURCE_EXHAUSTED when `desc` would be saved as a scene file of more
/// than `limit` bytes (scene_json_bytes: exact, in time proportional to the
/// description), naming what makes it large; else OK.
grpc::Status saved_file_check(const SceneDesc& desc, std::uint64_t limit) {
  std::uint64_t meshes = 0;
  const std::uint64_t file = scene_json_bytes(desc, &meshes);
  if (file <= limit) return grpc::Status::OK;
  std::size_t instances = 0;
  for (const ObjectDesc& o : desc.objects) instances += o.shape == Shape::Mesh ? 1 : 0;
  const std::string why =
      2 * meshes > file ? " (" + std::to_string(meshes) + " bytes of them the vertices and triangles that each of its " +
                              std::to_string(instances) + " mesh objects writes inline, instances included); " +
                              "place fewer instances of large meshes"
                        : " (" + std::to_string(desc.objects.size()) + " objects); split it into smaller scenes";
  return grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED,
                      "description: the scene would be saved as a file of " + std::to_string(file) +
                          " bytes, over the limit of " + std::to_string(limit) + " bytes (4 x --max-message-mib)" + why +
                          ", or raise --max-message-mib");
}

}  // namespace

// ---------------------------------------------------------------------------
// Service

Service::Service(ServiceConfig config, WorkerPool& pool, WorkerPool& builds, SceneStore& store,
                 const TokenTable& tokens, Metrics& metrics, Log log)
    : config_(std::move(config)),
      pool_(pool),
      builds_(builds),
      tokens_(tokens),
      metrics_(metrics),
      store_(store),
      log_(std::move(log)),
      fail_scene_(env_text("VOXVIS_TEST_FAIL_SCENE")),
      registry_(RegistryConfig{config_.scene_options, config_.memory_budget_bytes, config_.workers}, pool, store,
                metrics, log_, stopping_) {}

Service::~Service() = default;

void Service::add_misplaced(const std::string& id, const std::string& owner) {
  std::lock_guard<std::mutex> lock(misplaced_mu_);
  misplaced_[id] = owner;
}

grpc::Status Service::missing(const std::string& id) const {
  if (std::string owner = config_.shard.other_owner(id); !owner.empty()) return config_.shard.refusal(id, owner);
  return no_scene(id);
}

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
  if (!e) finish_unary(r, method, missing(id));
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
  out->set_mesh_objects(e.mesh_objects);
  out->set_mesh_triangles(e.mesh_triangles);
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
  if (std::string owner = config_.shard.other_owner(req->scene_id()); !owner.empty()) {
    finish_unary(r, "CreateScene", config_.shard.refusal(req->scene_id(), owner));
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
      grpc::Status too_large;
      switch (req->content_case()) {
        case v1::CreateSceneRequest::kDescription:
          s = desc_from_proto(req->description(), &desc);
          if (s) {
            // The scene is saved as a scene file, whose objects each carry
            // their mesh inline: instancing multiplies it. Measured exactly
            // (each mesh once) and refused before the text is made when a
            // restart could not read it back.
            too_large = saved_file_check(desc, config_.max_saved_scene_bytes);
            if (!too_large.ok()) break;
            json = scene_to_json(desc);
          }
          break;
        case v1::CreateSceneRequest::kSceneJson:
          from_json = true;
          json = req->scene_json();
          s = desc_from_json(json, &desc);
          break;
        default:
          s = Status::Error("content", "missing: set description or scene_json");
      }
      // Positions another server exported: placed before the build, the
      // clocks set before the scene is served.
      StartPositions start;
      if (s && req->has_positions()) {
        s = validate_time("positions.t", req->positions().t());
        if (s) s = moves_from_proto(req->positions().moves(), "positions.moves", &start.moves);
        if (s) s = place_dynamic(&desc, start.moves, true, "positions.moves");
        start.t = req->positions().t();
      }
      g = !too_large.ok() ? too_large
          : s             ? registry_.create(req->scene_id(), std::move(desc), json, from_json, true, &control,
                                             req->has_positions() ? &start : nullptr)
                          : invalid(s);
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
  if (req->only_if_misplaced() && find(req->scene_id())) {
    // The end of a move: a scene this server serves (after a restart made it
    // the owner again) keeps every move it acknowledged.
    finish_unary(r, "DeleteScene", config_.shard.still_served(req->scene_id()));
    return reactor;
  }
  grpc::Status g = registry_.remove(req->scene_id(), [this](SceneEntry& e) {
    std::lock_guard<std::mutex> lock(streams_mu_);
    for (Stream* s : streams_) s->stop_if(&e, deleted(e));
  });
  if (g.error_code() == grpc::StatusCode::NOT_FOUND) {
    // A scene kept for another shard goes with its files.
    std::lock_guard<std::mutex> lock(misplaced_mu_);
    if (misplaced_.count(req->scene_id())) {
      if (Status rm = store_.remove_scene(req->scene_id()); !rm) {
        g = grpc::Status(grpc::StatusCode::INTERNAL, "cannot remove the scene's files: " + rm.str());
      } else {
        misplaced_.erase(req->scene_id());
        log_("deleted scene '" + req->scene_id() + "' (kept for another shard)");
        g = grpc::Status::OK;
      }
    } else {
      g = missing(req->scene_id());
    }
  }
  finish_unary(r, "DeleteScene", g);
  return reactor;
}

grpc::ServerUnaryReactor* Service::ListScenes(grpc::CallbackServerContext* ctx,
                                              const grpc::ByteBuffer* in, grpc::ByteBuffer* out) {
  grpc::ServerUnaryReactor* reactor = nullptr;
  auto* r = start_call<v1::ListScenesRequest, v1::ListScenesResponse>(
      this, "ListScenes", ctx, Role::Viewer, in, out, &reactor);
  if (!r) return reactor;
  v1::ListScenesResponse* resp = &r->resp;
  for (const auto& e : registry_.list()) fill_info(*e, resp->add_scenes());
  {
    std::lock_guard<std::mutex> lock(misplaced_mu_);
    for (const auto& [id, owner] : misplaced_) {
      v1::MisplacedScene* m = resp->add_misplaced();
      m->set_scene_id(id);
      m->set_owner(owner);
    }
  }
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

grpc::ServerUnaryReactor* Service::ExportScene(grpc::CallbackServerContext* ctx,
                                               const grpc::ByteBuffer* in, grpc::ByteBuffer* out) {
  grpc::ServerUnaryReactor* reactor = nullptr;
  auto* r = start_call<v1::ExportSceneRequest, v1::ExportSceneResponse>(
      this, "ExportScene", ctx, Role::Admin, in, out, &reactor);
  if (!r) return reactor;
  const std::string id = r->req.scene_id();
  if (grpc::Status s = check_scene_id(id); !s.ok()) {
    finish_unary(r, "ExportScene", s);
    return reactor;
  }
  if (r->req.only_if_misplaced() && find(id)) {
    // A move's export of a scene this server serves: moves it acknowledges
    // after the export would be lost with the copy.
    finish_unary(r, "ExportScene", config_.shard.still_served(id));
    return reactor;
  }
  // Reading the files takes a while for a large scene: on the build thread.
  builds_.submit(ctx->peer(), [this, r, id](Scratch&) {
    grpc::Status g;
    try {
      std::shared_ptr<SceneEntry> e = find(id);
      bool kept = false;
      if (!e) {
        std::lock_guard<std::mutex> lock(misplaced_mu_);
        kept = misplaced_.count(id) > 0;
      }
      StoredScene stored;
      if (!e && !kept) {
        g = missing(id);
      } else if (Status s = store_.read(id, &stored); !s) {
        // Deleted meanwhile, or its files are unreadable.
        bool still_kept = false;
        {
          std::lock_guard<std::mutex> lock(misplaced_mu_);
          still_kept = misplaced_.count(id) > 0;
        }
        g = (e ? e->deleted.load() : !still_kept)
                ? missing(id)
                : grpc::Status(grpc::StatusCode::INTERNAL, "cannot read the scene's files: " + s.str());
      } else {
        v1::ExportSceneResponse* resp = &r->resp;
        resp->set_scene_id(id);
        resp->set_scene_json(std::move(stored.json));
        // A served scene's positions are the engine's, newer than the last
        // save; a kept one's are its file's. None when they never moved.
        std::vector<Move> moves;
        double t = 0.0;
        bool have = false;
        if (e && e->dynamic_objects > 0 && (stored.t || e->moves_applied.load() > 0)) {
          moves = e->scene->dynamic_centers(&t);
          have = true;
        } else if (!e && stored.t) {
          moves = std::move(stored.positions);
          t = *stored.t;
          have = true;
        }
        if (have) {
          v1::ScenePositions* p = resp->mutable_positions();
          p->set_t(t);
          for (const Move& m : moves) {
            v1::Move* w = p->add_moves();
            w->set_id(m.id);
            vec_to_proto(m.center, w->mutable_center());
            if (m.has_rotation) {
              v1::Quat* q = w->mutable_rotation();
              q->set_w(m.rotation.w);
              q->set_x(m.rotation.x);
              q->set_y(m.rotation.y);
              q->set_z(m.rotation.z);
            }
          }
        }
        const std::uint64_t bytes = resp->ByteSizeLong();
        if (bytes > config_.max_message_bytes) {
          resp->Clear();
          g = grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED,
                           "scene '" + id + "' exports as a message of " + std::to_string(bytes) +
                               " bytes, over --max-message-mib (" + std::to_string(config_.max_message_bytes) +
                               " bytes): copy " + stored.json_path +
                               " (and its .positions file) into the owner's data directory instead, with "
                               "both servers stopped (docs/deploy.md)");
        }
      }
    } catch (const std::exception& x) {
      log_("internal error exporting scene '" + id + "': " + x.what());
      g = grpc::Status(grpc::StatusCode::INTERNAL, std::string("internal error exporting the scene: ") + x.what());
    }
    finish_unary(r, "ExportScene", g);
  });
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
    FrameResult result;
    bool check = false;
    if (grpc::Status g = serve_frame(*e, nullptr, camera, t, scratch, &result, &check); !g.ok()) {
      finish_unary(r, "GetPvs", g);
      return;
    }
    const double latency = std::chrono::duration<double>(Clock::now() - received).count();
    answer_frame(*e, result, v1::PVS_FULL, nullptr, latency, resp);
    const std::string peer = check ? ctx->peer() : std::string();
    finish_unary(r, "GetPvs", grpc::Status::OK);
    if (check) verify_served(*e, peer + " (GetPvs)", 0, camera, result);
  });
  return reactor;
}

grpc::Status Service::serve_frame(SceneEntry& e, FrameViewer* viewer, const Camera& camera, double t,
                                  Scratch& scratch, FrameResult* result, bool* check) {
  if (e.deleted.load()) return deleted(e);
  Scene& scene = *e.scene;
  // The scene's clock is shared: a time behind it is taken as it, one too
  // far beyond the simulation's as its limit.
  const double at = e.view_time(t, config_.max_view_lead_s);
  const bool cpu = e.metrics && e.metrics->wants_engine_cpu();
  const double cpu0 = cpu ? thread_cpu_seconds() : 0.0;
  const grpc::Status g = guarded(e, "frame", [&] {
    auto frame = [&](ViewerId id) {
      Status s = scene.frame(id, camera, at, scratch, result, Scene::Clock::Latest);
      return s ? grpc::Status::OK : invalid(s);
    };
    if (viewer == nullptr) {
      // A one-frame viewer, removed however the frame ends.
      struct OneFrameViewer {
        Scene& scene;
        const ViewerId id = scene.add_viewer();
        ~OneFrameViewer() { scene.remove_viewer(id); }
      } one{scene};
      return frame(one.id);
    }
    if (!viewer->added) {
      viewer->id = scene.add_viewer();
      viewer->added = true;
    }
    return frame(viewer->id);
  });
  if (cpu) e.metrics->engine_cpu(thread_cpu_seconds() - cpu0);
  if (!g.ok()) return g;
  e.after_frame(*result);
  if (check) *check = verify_sample();
  return grpc::Status::OK;
}

void Service::release_viewer(const std::string& client, const std::shared_ptr<SceneEntry>& e,
                             const FrameViewer& viewer) {
  if (!viewer.added) return;
  pool_.submit(client, [e, v = viewer.id](Scratch&) {
    if (!e->deleted.load()) e->scene->remove_viewer(v);
  });
}

grpc::Status Service::apply_batch(SceneEntry& e, double t, const std::vector<Move>& moves,
                                  const std::string& field_prefix, MoveReport* report) {
  // The scene's batches and its simulation clock are its strand's alone.
  VOXVIS_ASSERT(e.strand && e.strand->runs_here());
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
