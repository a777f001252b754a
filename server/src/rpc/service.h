// service.h — the Visibility service (proto/voxvis/v1/voxvis.proto) on gRPC's
// callback API. It only dispatches: each RPC goes to its reactor (the
// streams, streams.h) or function (the unary calls, unary_calls.h), which
// work with two layers beneath: Admission (admission.h: tokens, calls in
// progress, live streams, shutdown) and Serving (serving.h: the scenes'
// frames, move batches and verify mode), over the scenes the SceneRegistry
// keeps (scene_registry.h).
//
// Threads: gRPC's callback threads run the reactors' reactions, which only
// check messages, update per-stream state under the stream's mutex, and post
// work; they never wait for a scene. Frames and GetPvs run as jobs on the
// WorkerPool (pool.h), frames of different viewers of a scene in parallel;
// a scene's move batches run through its Strand, one at a time in order. A
// stream has at most one job and one write in flight, and keeps at most one
// newer request and one newer answer: memory per stream is bounded whatever
// the client does.
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <grpcpp/grpcpp.h>

#include "rpc/unary_calls.h"
#include "scenes/metrics.h"
#include "scenes/pool.h"
#include "scenes/scene_registry.h"
#include "scenes/store.h"
#include "scenes/verifier.h"
#include "serving/admission.h"
#include "serving/auth.h"
#include "serving/service_config.h"
#include "serving/serving.h"
#include "voxvis/v1/voxvis.grpc.pb.h"

namespace voxvis::server {

/// Every method raw (calls.h says why): the generated base with each typed
/// callback method replaced by its ByteBuffer form.
using RawVisibilityService = v1::Visibility::WithRawCallbackMethod_CreateScene<
    v1::Visibility::WithRawCallbackMethod_DeleteScene<
        v1::Visibility::WithRawCallbackMethod_ListScenes<
            v1::Visibility::WithRawCallbackMethod_GetSceneStats<
                v1::Visibility::WithRawCallbackMethod_View<
                    v1::Visibility::WithRawCallbackMethod_Simulate<
                        v1::Visibility::WithRawCallbackMethod_Tick<
                            v1::Visibility::WithRawCallbackMethod_GetPvs<
                                v1::Visibility::WithRawCallbackMethod_ExportScene<v1::Visibility::Service>>>>>>>>>;

class Service final : public RawVisibilityService {
 public:
  using Log = std::function<void(const std::string&)>;
  /// `pool` runs frames and move batches; `builds` runs scene builds
  /// (CreateScene), which must never wait behind frames nor hold their workers.
  Service(ServiceConfig config, WorkerPool& pool, WorkerPool& builds, SceneStore& store,
          const TokenTable& tokens, Metrics& metrics, Log log);
  ~Service() override;

  // Start-up and shutdown (server.cpp), before and after serving.

  /// Loads a scene at start (data directory or --scene file) on the
  /// caller's thread; SceneRegistry::load says how.
  Status load_scene(const std::string& id, const std::string& json, const std::string& source,
                    const std::vector<Move>* positions, std::optional<double> t, bool persist) {
    return registry_.load(id, json, source, positions, t, persist);
  }
  bool has_scene(const std::string& id) const { return registry_.find(id) != nullptr; }
  /// A scene of the data directory that another shard owns (SceneRegistry::add_misplaced).
  void add_misplaced(const std::string& id, const std::string& owner) { registry_.add_misplaced(id, owner); }
  /// Verify mode (--verify-fraction): set before serving; null when off.
  void set_verifier(Verifier* v) { serving_.set_verifier(v); }
  /// Ends every stream with UNAVAILABLE after its in-flight frame and refuses
  /// new ones. Call before grpc::Server::Shutdown.
  void begin_shutdown() { admission_.begin_shutdown(); }
  /// Writes the positions of every scene whose dynamic objects moved since
  /// the last save.
  void save_positions() { registry_.save_positions(); }
  /// Queued requests answered without running (client gone, server stopping).
  std::uint64_t dropped() const { return admission_.dropped(); }

  // RPCs (see the .proto), raw: requests are parsed by the calls themselves.
  using Raw = grpc::ByteBuffer;
  grpc::ServerUnaryReactor* CreateScene(grpc::CallbackServerContext* ctx, const Raw* in, Raw* out) override;
  grpc::ServerUnaryReactor* DeleteScene(grpc::CallbackServerContext* ctx, const Raw* in, Raw* out) override;
  grpc::ServerUnaryReactor* ListScenes(grpc::CallbackServerContext* ctx, const Raw* in, Raw* out) override;
  grpc::ServerUnaryReactor* GetSceneStats(grpc::CallbackServerContext* ctx, const Raw* in, Raw* out) override;
  grpc::ServerBidiReactor<Raw, Raw>* View(grpc::CallbackServerContext* ctx) override;
  grpc::ServerBidiReactor<Raw, Raw>* Simulate(grpc::CallbackServerContext* ctx) override;
  grpc::ServerBidiReactor<Raw, Raw>* Tick(grpc::CallbackServerContext* ctx) override;
  grpc::ServerUnaryReactor* GetPvs(grpc::CallbackServerContext* ctx, const Raw* in, Raw* out) override;
  grpc::ServerUnaryReactor* ExportScene(grpc::CallbackServerContext* ctx, const Raw* in, Raw* out) override;

 private:
  const ServiceConfig config_;
  Admission admission_;
  SceneRegistry registry_;
  Serving serving_;
  UnaryDeps unary_;
};

}  // namespace voxvis::server
