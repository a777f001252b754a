#include "rpc/service.h"

#include <utility>

#include "rpc/streams.h"

namespace voxvis::server {

Service::Service(ServiceConfig config, WorkerPool& pool, WorkerPool& builds, SceneStore& store,
                 const TokenTable& tokens, Metrics& metrics, Log log)
    : config_(std::move(config)),
      admission_(tokens, metrics, config_.max_calls),
      registry_(RegistryConfig{config_.scene_options, config_.memory_budget_bytes, config_.workers}, pool, store,
                metrics, log, admission_.stopping()),
      serving_(config_, pool, registry_, log),
      unary_{admission_, serving_, registry_, store, builds, config_, std::move(log)} {}

Service::~Service() = default;

grpc::ServerUnaryReactor* Service::CreateScene(grpc::CallbackServerContext* ctx, const Raw* in, Raw* out) {
  return create_scene(unary_, ctx, in, out);
}
grpc::ServerUnaryReactor* Service::DeleteScene(grpc::CallbackServerContext* ctx, const Raw* in, Raw* out) {
  return delete_scene(unary_, ctx, in, out);
}
grpc::ServerUnaryReactor* Service::ListScenes(grpc::CallbackServerContext* ctx, const Raw* in, Raw* out) {
  return list_scenes(unary_, ctx, in, out);
}
grpc::ServerUnaryReactor* Service::GetSceneStats(grpc::CallbackServerContext* ctx, const Raw* in, Raw* out) {
  return get_scene_stats(unary_, ctx, in, out);
}
grpc::ServerUnaryReactor* Service::GetPvs(grpc::CallbackServerContext* ctx, const Raw* in, Raw* out) {
  return get_pvs(unary_, ctx, in, out);
}
grpc::ServerUnaryReactor* Service::ExportScene(grpc::CallbackServerContext* ctx, const Raw* in, Raw* out) {
  return export_scene(unary_, ctx, in, out);
}
grpc::ServerBidiReactor<grpc::ByteBuffer, grpc::ByteBuffer>* Service::View(grpc::CallbackServerContext* ctx) {
  return new_view_stream(admission_, serving_, ctx);
}
grpc::ServerBidiReactor<grpc::ByteBuffer, grpc::ByteBuffer>* Service::Simulate(grpc::CallbackServerContext* ctx) {
  return new_simulate_stream(admission_, serving_, ctx);
}
grpc::ServerBidiReactor<grpc::ByteBuffer, grpc::ByteBuffer>* Service::Tick(grpc::CallbackServerContext* ctx) {
  return new_tick_stream(admission_, serving_, ctx);
}

}  // namespace voxvis::server
