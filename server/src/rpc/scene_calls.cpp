// scene_calls.cpp — DeleteScene, ListScenes and GetSceneStats (unary_calls.h).
#include <mutex>
#include <string>

#include "rpc/unary_calls.h"
#include "wire/convert.h"

namespace voxvis::server {

void fill_info(const SceneEntry& e, v1::SceneInfo* out) {
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

std::shared_ptr<SceneEntry> find_or_finish(UnaryDeps& d, UnaryCall* r, const char* method, const std::string& id) {
  if (grpc::Status s = check_scene_id(id); !s.ok()) {
    d.admission.finish_unary(r, method, s);
    return nullptr;
  }
  std::shared_ptr<SceneEntry> e = d.serving.find(id);
  if (!e) d.admission.finish_unary(r, method, d.serving.missing(id));
  return e;
}

grpc::Status check_move_step(UnaryDeps& d, const std::string& id, bool only_if_misplaced) {
  if (grpc::Status s = check_scene_id(id); !s.ok()) return s;
  if (only_if_misplaced && d.serving.find(id)) return d.config.shard.still_served(id);
  return grpc::Status::OK;
}

bool answered_unrun(UnaryDeps& d, grpc::CallbackServerContext* ctx, UnaryCall* r, const char* method) {
  if (ctx->IsCancelled()) {
    d.admission.count_dropped();
    r->finish(grpc::Status(grpc::StatusCode::CANCELLED, "cancelled"));
    return true;
  }
  if (d.admission.shutting_down()) {
    d.admission.count_dropped();
    d.admission.finish_unary(r, method, shutting_down_status());
    return true;
  }
  return false;
}

grpc::ServerUnaryReactor* delete_scene(UnaryDeps& d, grpc::CallbackServerContext* ctx, const Raw* in, Raw* out) {
  grpc::ServerUnaryReactor* reactor = nullptr;
  auto* r = d.admission.start_unary<v1::DeleteSceneRequest, v1::DeleteSceneResponse>("DeleteScene", ctx, Role::Admin,
                                                                                      in, out, &reactor);
  if (!r) return reactor;
  const std::string& id = r->req.scene_id();
  // The end of a move (only_if_misplaced): a scene this server serves
  // (after a restart made it the owner again) keeps every move it acknowledged.
  if (grpc::Status s = check_move_step(d, id, r->req.only_if_misplaced()); !s.ok()) {
    d.admission.finish_unary(r, "DeleteScene", s);
    return reactor;
  }
  grpc::Status g = d.registry.remove(id, [&d](SceneEntry& e) { d.admission.stop_streams(e, deleted(e.id)); });
  if (g.error_code() == grpc::StatusCode::NOT_FOUND) {
    // A scene kept for another shard goes with its files.
    g = d.registry.remove_misplaced(id);
    if (g.error_code() == grpc::StatusCode::NOT_FOUND) g = d.serving.missing(id);
  }
  d.admission.finish_unary(r, "DeleteScene", g);
  return reactor;
}

grpc::ServerUnaryReactor* list_scenes(UnaryDeps& d, grpc::CallbackServerContext* ctx, const Raw* in, Raw* out) {
  grpc::ServerUnaryReactor* reactor = nullptr;
  auto* r = d.admission.start_unary<v1::ListScenesRequest, v1::ListScenesResponse>("ListScenes", ctx, Role::Viewer,
                                                                                    in, out, &reactor);
  if (!r) return reactor;
  for (const auto& e : d.registry.list()) fill_info(*e, r->resp.add_scenes());
  for (const auto& [id, owner] : d.registry.misplaced()) {
    v1::MisplacedScene* m = r->resp.add_misplaced();
    m->set_scene_id(id);
    m->set_owner(owner);
  }
  d.admission.finish_unary(r, "ListScenes", grpc::Status::OK);
  return reactor;
}

grpc::ServerUnaryReactor* get_scene_stats(UnaryDeps& d, grpc::CallbackServerContext* ctx, const Raw* in, Raw* out) {
  grpc::ServerUnaryReactor* reactor = nullptr;
  auto* r = d.admission.start_unary<v1::GetSceneStatsRequest, v1::SceneInfo>("GetSceneStats", ctx, Role::Viewer, in,
                                                                              out, &reactor);
  if (!r) return reactor;
  std::shared_ptr<SceneEntry> e = find_or_finish(d, r, "GetSceneStats", r->req.scene_id());
  if (!e) return reactor;
  fill_info(*e, &r->resp);
  d.admission.finish_unary(r, "GetSceneStats", grpc::Status::OK);
  return reactor;
}

}  // namespace voxvis::server
