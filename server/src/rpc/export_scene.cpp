// export_scene.cpp — ExportScene (unary_calls.h): a scene's files and
// positions as one message, read on the build thread.
#include <exception>
#include <string>
#include <utility>
#include <vector>

#include "rpc/unary_calls.h"
#include "wire/convert.h"

namespace voxvis::server {
namespace {

using Call = TypedUnaryCall<v1::ExportSceneRequest, v1::ExportSceneResponse>;

void moves_to_proto(double t, const std::vector<Move>& moves, v1::ScenePositions* p) {
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

/// The positions to export: a served scene's are the engine's, newer than
/// the last save; a kept one's (`e` null) are its file's. None when they
/// never moved.
void put_positions(const SceneEntry* e, StoredScene& stored, v1::ExportSceneResponse* resp) {
  if (e && e->dynamic_objects > 0 && (stored.t || e->moves_applied.load() > 0)) {
    double t = 0.0;
    const std::vector<Move> moves = e->scene->dynamic_centers(&t);
    moves_to_proto(t, moves, resp->mutable_positions());
  } else if (!e && stored.t) {
    moves_to_proto(*stored.t, stored.positions, resp->mutable_positions());
  }
}

/// Reads scene `id` (served, or kept for another shard) into the answer.
grpc::Status read_export(UnaryDeps& d, const std::string& id, v1::ExportSceneResponse* resp) {
  const std::shared_ptr<SceneEntry> e = d.serving.find(id);
  if (!e && !d.registry.is_misplaced(id)) return d.serving.missing(id);
  StoredScene stored;
  if (Status s = d.store.read(id, &stored); !s) {
    // Deleted meanwhile, or its files are unreadable.
    const bool gone = e ? e->deleted.load() : !d.registry.is_misplaced(id);
    return gone ? d.serving.missing(id)
                : grpc::Status(grpc::StatusCode::INTERNAL, "cannot read the scene's files: " + s.str());
  }
  resp->set_scene_id(id);
  resp->set_scene_json(std::move(stored.json));
  put_positions(e.get(), stored, resp);
  const std::uint64_t bytes = resp->ByteSizeLong();
  if (bytes <= d.config.max_message_bytes) return grpc::Status::OK;
  resp->Clear();
  return grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED,
                      "scene '" + id + "' exports as a message of " + std::to_string(bytes) +
                          " bytes, over --max-message-mib (" + std::to_string(d.config.max_message_bytes) +
                          " bytes): copy " + stored.json_path +
                          " (and its .positions file) into the owner's data directory instead, with "
                          "both servers stopped (docs/deploy.md)");
}

}  // namespace

grpc::ServerUnaryReactor* export_scene(UnaryDeps& d, grpc::CallbackServerContext* ctx, const Raw* in, Raw* out) {
  grpc::ServerUnaryReactor* reactor = nullptr;
  Call* r = d.admission.start_unary<v1::ExportSceneRequest, v1::ExportSceneResponse>("ExportScene", ctx, Role::Admin,
                                                                                     in, out, &reactor);
  if (!r) return reactor;
  const std::string id = r->req.scene_id();
  // A move's export (only_if_misplaced) of a scene this server serves: moves
  // it acknowledges after the export would be lost with the copy.
  if (grpc::Status s = check_move_step(d, id, r->req.only_if_misplaced()); !s.ok()) {
    d.admission.finish_unary(r, "ExportScene", s);
    return reactor;
  }
  // Reading the files takes a while for a large scene: on the build thread.
  d.builds.submit(ctx->peer(), [&d, r, id](Scratch&) {
    grpc::Status g;
    try {
      g = read_export(d, id, &r->resp);
    } catch (const std::exception& x) {
      d.log("internal error exporting scene '" + id + "': " + x.what());
      g = grpc::Status(grpc::StatusCode::INTERNAL, std::string("internal error exporting the scene: ") + x.what());
    }
    d.admission.finish_unary(r, "ExportScene", g);
  });
  return reactor;
}

}  // namespace voxvis::server
