// unary_calls.h — the service's unary RPCs, a function each: the reaction
// that starts the call (admission.h) and, where the work takes a while, the
// job that ends it. scene_calls.cpp: DeleteScene, ListScenes,
// GetSceneStats; create_scene.cpp: CreateScene; export_scene.cpp:
// ExportScene; get_pvs.cpp: GetPvs. Each returns the call's reactor.
#pragma once

#include <functional>
#include <memory>
#include <string>

#include <grpcpp/grpcpp.h>

#include "scenes/pool.h"
#include "scenes/scene_entry.h"
#include "scenes/scene_registry.h"
#include "scenes/store.h"
#include "serving/admission.h"
#include "serving/service_config.h"
#include "serving/serving.h"
#include "voxvis/v1/voxvis.pb.h"
#include "wire/calls.h"

namespace voxvis::server {

/// What the unary calls work with.
struct UnaryDeps {
  Admission& admission;
  Serving& serving;
  SceneRegistry& registry;
  SceneStore& store;
  WorkerPool& builds;  ///< Runs builds and exports: never behind frames, never on their workers.
  const ServiceConfig& config;
  std::function<void(const std::string&)> log;
};

using Raw = grpc::ByteBuffer;
grpc::ServerUnaryReactor* create_scene(UnaryDeps& d, grpc::CallbackServerContext* ctx, const Raw* in, Raw* out);
grpc::ServerUnaryReactor* delete_scene(UnaryDeps& d, grpc::CallbackServerContext* ctx, const Raw* in, Raw* out);
grpc::ServerUnaryReactor* list_scenes(UnaryDeps& d, grpc::CallbackServerContext* ctx, const Raw* in, Raw* out);
grpc::ServerUnaryReactor* get_scene_stats(UnaryDeps& d, grpc::CallbackServerContext* ctx, const Raw* in, Raw* out);
grpc::ServerUnaryReactor* export_scene(UnaryDeps& d, grpc::CallbackServerContext* ctx, const Raw* in, Raw* out);
grpc::ServerUnaryReactor* get_pvs(UnaryDeps& d, grpc::CallbackServerContext* ctx, const Raw* in, Raw* out);

/// A scene's statistics as its SceneInfo (CreateScene, ListScenes, GetSceneStats).
void fill_info(const SceneEntry& e, v1::SceneInfo* out);
/// The scene `id` names, or null after finishing the call (INVALID_ARGUMENT
/// for an invalid id, Serving::missing's status).
std::shared_ptr<SceneEntry> find_or_finish(UnaryDeps& d, UnaryCall* r, const char* method, const std::string& id);
/// The scene id of a step of `voxvis rebalance` (DeleteScene, ExportScene):
/// INVALID_ARGUMENT when invalid; with `only_if_misplaced`, FAILED_PRECONDITION
/// when this server serves the scene (ShardIdentity::still_served: the
/// step would lose moves it acknowledged); else OK.
grpc::Status check_move_step(UnaryDeps& d, const std::string& id, bool only_if_misplaced);
/// At the start of a queued call's job: answers the call without running it
/// when nobody waits for it any more (CANCELLED) or the server is stopping
/// (UNAVAILABLE), counting it dropped, and returns true; else false.
bool answered_unrun(UnaryDeps& d, grpc::CallbackServerContext* ctx, UnaryCall* r, const char* method);

}  // namespace voxvis::server
