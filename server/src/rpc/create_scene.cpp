// create_scene.cpp — CreateScene (unary_calls.h): the request checked on the
// callback thread, the scene parsed and built on the build thread.
#include <chrono>
#include <exception>
#include <string>
#include <utility>

#include "rpc/unary_calls.h"
#include "voxvis/format.h"
#include "wire/convert.h"

namespace voxvis::server {
namespace {

using Call = TypedUnaryCall<v1::CreateSceneRequest, v1::SceneInfo>;

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

/// What a request asks to build: the scene, its text as it is to be saved,
/// and where its dynamic objects start.
struct Content {
  SceneDesc desc;
  std::string json;
  bool from_json = false;  ///< Errors name the text's lines, not a description's fields.
  StartPositions start;
};

/// The scene of the request's description or scene_json. A description is
/// saved as a scene file whose objects each carry their mesh inline
/// (instancing multiplies it): measured exactly (each mesh once) and refused
/// before the text is made when a restart could not read it back.
grpc::Status read_scene(const v1::CreateSceneRequest& req, std::uint64_t max_saved_bytes, Content* c) {
  Status s;
  switch (req.content_case()) {
    case v1::CreateSceneRequest::kDescription:
      s = desc_from_proto(req.description(), &c->desc);
      if (!s) return invalid(s);
      if (grpc::Status too_large = saved_file_check(c->desc, max_saved_bytes); !too_large.ok()) return too_large;
      c->json = scene_to_json(c->desc);
      return grpc::Status::OK;
    case v1::CreateSceneRequest::kSceneJson:
      c->from_json = true;
      c->json = req.scene_json();
      s = desc_from_json(c->json, &c->desc);
      return s ? grpc::Status::OK : invalid(s);
    default:
      return invalid(Status::Error("content", "missing: set description or scene_json"));
  }
}

/// Positions another server exported: placed before the build, the clocks
/// set before the scene is served.
grpc::Status read_positions(const v1::CreateSceneRequest& req, Content* c) {
  if (!req.has_positions()) return grpc::Status::OK;
  Status s = validate_time("positions.t", req.positions().t());
  if (s) s = moves_from_proto(req.positions().moves(), "positions.moves", &c->start.moves);
  if (s) s = place_dynamic(&c->desc, c->start.moves, true, "positions.moves");
  c->start.t = req.positions().t();
  return s ? grpc::Status::OK : invalid(s);
}

/// Reads, builds and registers the scene; fills the answer when it is served.
grpc::Status build(UnaryDeps& d, Call* r, const BuildControl& control) {
  const v1::CreateSceneRequest& req = r->req;
  Content c;
  if (grpc::Status g = read_scene(req, d.config.max_saved_scene_bytes, &c); !g.ok()) return g;
  if (grpc::Status g = read_positions(req, &c); !g.ok()) return g;
  grpc::Status g = d.registry.create(req.scene_id(), std::move(c.desc), c.json, c.from_json, true, &control,
                                     req.has_positions() ? &c.start : nullptr);
  if (g.ok()) {
    fill_info(*d.serving.find(req.scene_id()), &r->resp);
    d.log("created scene '" + req.scene_id() + "'");
  } else if (g.error_code() == grpc::StatusCode::CANCELLED) {
    d.log("build of scene '" + req.scene_id() + "' stopped: its client went away or its deadline passed");
  }
  return g;
}

/// The build thread's job. A build stops when its client has gone, its
/// deadline has passed or the server is stopping. Everything may throw
/// (memory exhausted by a huge document, say): then the call ends INTERNAL
/// and the server goes on.
void build_job(UnaryDeps& d, grpc::CallbackServerContext* ctx, Call* r) {
  if (answered_unrun(d, ctx, r, "CreateScene")) return;
  const auto deadline = ctx->deadline();
  BuildControl control;
  control.cancelled = [&d, ctx, deadline] {
    return d.admission.shutting_down() || ctx->IsCancelled() || std::chrono::system_clock::now() > deadline;
  };
  grpc::Status g;
  try {
    g = build(d, r, control);
  } catch (const std::exception& e) {
    d.log("internal error creating scene '" + r->req.scene_id() + "': " + e.what());
    g = grpc::Status(grpc::StatusCode::INTERNAL, std::string("internal error creating the scene: ") + e.what());
  }
  d.admission.finish_unary(r, "CreateScene", g);
}

}  // namespace

grpc::ServerUnaryReactor* create_scene(UnaryDeps& d, grpc::CallbackServerContext* ctx, const Raw* in, Raw* out) {
  grpc::ServerUnaryReactor* reactor = nullptr;
  Call* r = d.admission.start_unary<v1::CreateSceneRequest, v1::SceneInfo>("CreateScene", ctx, Role::Admin, in, out,
                                                                           &reactor);
  if (!r) return reactor;
  const std::string& id = r->req.scene_id();
  if (grpc::Status s = check_scene_id(id); !s.ok()) {
    d.admission.finish_unary(r, "CreateScene", s);
    return reactor;
  }
  if (std::string owner = d.config.shard.other_owner(id); !owner.empty()) {
    d.admission.finish_unary(r, "CreateScene", d.config.shard.refusal(id, owner));
    return reactor;
  }
  // Parsing and building a grid take long: off the callback thread, and on
  // the build thread, not a frame worker.
  d.builds.submit(ctx->peer(), [&d, ctx, r](Scratch&) { build_job(d, ctx, r); });
  return reactor;
}

}  // namespace voxvis::server
