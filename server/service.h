// service.h — the Visibility service (proto/voxvis/v1/voxvis.proto) on gRPC's
// callback API. Its scenes are kept by a SceneRegistry (scene_registry.h).
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

#include <atomic>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <unordered_set>
#include <vector>

#include <grpcpp/grpcpp.h>

#include "auth.h"
#include "calls.h"
#include "metrics.h"
#include "pool.h"
#include "scene_entry.h"
#include "scene_registry.h"
#include "shard.h"
#include "store.h"
#include "verifier.h"
#include "voxvis/scene.h"
#include "voxvis/v1/voxvis.grpc.pb.h"

namespace voxvis::server {

/// Server-wide settings (voxvis-server's options; docs/server.md).
struct ServiceConfig {
  SceneOptions scene_options;
  std::uint64_t memory_budget_bytes = 0;  ///< Sum of scenes' estimated bytes allowed.
  unsigned workers = 1;
  /// How far beyond the simulation's clock a viewer's frame may run, seconds.
  double max_view_lead_s = 1.0;
  /// How far one simulation batch may advance a scene's clock, seconds.
  double max_time_step_s = 3600.0;
  /// Calls in progress (streams and unary calls), server-wide.
  int max_calls = 4096;
  /// Largest scene file a CreateScene from a description may be saved as
  /// (saved_scene_bytes): 4 x --max-message-mib, room for any description
  /// without instancing that fits a message, while a restart, which reads
  /// the file back, needs several times its size.
  std::uint64_t max_saved_scene_bytes = std::uint64_t{256} << 20;
  /// Largest message sent (--max-message-mib): an ExportScene answer above
  /// it is refused, naming the files to copy instead.
  std::uint64_t max_message_bytes = std::uint64_t{64} << 20;
  /// The server's place in a fleet (--shard, --fleet); none: every scene is its own.
  ShardIdentity shard;
};

/// A stream the service can end from outside (shutdown, scene deletion).
class Stream {
 public:
  virtual ~Stream() = default;
  /// Ends the stream with `status` once its in-flight frame is answered, when
  /// `scene` is null or is the stream's scene.
  virtual void stop_if(const SceneEntry* scene, const grpc::Status& status) = 0;
};

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

  /// Loads a scene at start (data directory or --scene file). Runs on the
  /// caller's thread before the server accepts calls. `positions`, when
  /// given, replace the centres of the dynamic objects they name
  /// (SceneRegistry::load).
  Status load_scene(const std::string& id, const std::string& json, const std::string& source,
                    const std::vector<Move>* positions, std::optional<double> t, bool persist) {
    return registry_.load(id, json, source, positions, t, persist);
  }
  bool has_scene(const std::string& id) const { return find(id) != nullptr; }
  /// Records a scene of the data directory that another shard owns: kept on
  /// disk, not served; listed, exported and deleted (ListScenes, ExportScene,
  /// DeleteScene) so that `voxvis rebalance` can move it. Call before serving.
  void add_misplaced(const std::string& id, const std::string& owner);
  /// The status of a call on a scene this server does not have: the shard
  /// identity's refusal naming the owner when the id is another shard's,
  /// else NOT_FOUND.
  grpc::Status missing(const std::string& id) const;

  /// Ends every stream with UNAVAILABLE after its in-flight frame and refuses
  /// new ones. Call before grpc::Server::Shutdown.
  void begin_shutdown();
  /// Writes the positions of every scene whose dynamic objects moved since
  /// the last save.
  void save_positions() { registry_.save_positions(); }

  // RPCs (see the .proto), raw: requests are parsed in calls.h's helpers.
  using Raw = grpc::ByteBuffer;
  grpc::ServerUnaryReactor* CreateScene(grpc::CallbackServerContext* ctx, const Raw* in,
                                        Raw* out) override;
  grpc::ServerUnaryReactor* DeleteScene(grpc::CallbackServerContext* ctx, const Raw* in,
                                        Raw* out) override;
  grpc::ServerUnaryReactor* ListScenes(grpc::CallbackServerContext* ctx, const Raw* in,
                                       Raw* out) override;
  grpc::ServerUnaryReactor* GetSceneStats(grpc::CallbackServerContext* ctx, const Raw* in,
                                          Raw* out) override;
  grpc::ServerBidiReactor<Raw, Raw>* View(grpc::CallbackServerContext* ctx) override;
  grpc::ServerBidiReactor<Raw, Raw>* Simulate(grpc::CallbackServerContext* ctx) override;
  grpc::ServerBidiReactor<Raw, Raw>* Tick(grpc::CallbackServerContext* ctx) override;
  grpc::ServerUnaryReactor* GetPvs(grpc::CallbackServerContext* ctx, const Raw* in,
                                   Raw* out) override;
  grpc::ServerUnaryReactor* ExportScene(grpc::CallbackServerContext* ctx, const Raw* in,
                                        Raw* out) override;

  // For the reactors.
  std::shared_ptr<SceneEntry> find(const std::string& id) const { return registry_.find(id); }
  const TokenTable& tokens() const { return tokens_; }
  Metrics& metrics() { return metrics_; }
  WorkerPool& pool() { return pool_; }
  const ServiceConfig& config() const { return config_; }
  /// True from begin_shutdown on: queued work is answered without running.
  bool shutting_down() const { return stopping_.load(std::memory_order_relaxed); }
  /// Counts a queued request answered without running: its client had gone
  /// or the server was stopping.
  void count_dropped() { dropped_.fetch_add(1, std::memory_order_relaxed); }
  /// Takes a place among the calls in progress: OK, or RESOURCE_EXHAUSTED
  /// when --max-calls are under way. Each OK is paired with a leave_call().
  grpc::Status enter_call();
  void leave_call() { calls_.fetch_sub(1, std::memory_order_relaxed); }
  std::uint64_t dropped() const { return dropped_.load(std::memory_order_relaxed); }
  /// Registers a live stream; false when the server is shutting down.
  bool add_stream(Stream* s);
  void remove_stream(Stream* s);
  /// Counts a call ended with a non-OK status.
  void count_error(const char* method, const grpc::Status& status);
  /// Verify mode (--verify-fraction): set before serving; null when off.
  void set_verifier(Verifier* v) {
    verifier_ = v;
    registry_.keep_objects(v != nullptr);
  }
  /// Whether the frame about to be served is one to verify.
  bool verify_sample() { return verifier_ != nullptr && verifier_->sample(); }
  /// Hands a served frame to the verifier, after its answer: reads the
  /// dynamic objects' positions, which must still be those the frame saw
  /// (FrameResult::positions_epoch), else the frame is dropped (counted).
  void verify_served(const SceneEntry& e, const std::string& viewer, std::uint64_t frame, const Camera& camera,
                     const FrameResult& result);
  /// Serves one frame of scene `e`: GetPvs, View and Tick alike, in a pool
  /// job. NOT_FOUND when the scene was deleted; else the frame of `viewer`
  /// (added by its first frame; null: a viewer for this frame only) at `t`
  /// as the scene's clock allows (SceneEntry::view_time), run by guarded()
  /// into `*result`, then the scene's bookkeeping (SceneEntry::after_frame).
  /// `*check`, when given, says whether verify mode samples the frame: the
  /// caller hands it to verify_served after its answer. The answer itself is
  /// answer_frame's (frame_answer.h), when the call writes it.
  grpc::Status serve_frame(SceneEntry& e, FrameViewer* viewer, const Camera& camera, double t, Scratch& scratch,
                           FrameResult* result, bool* check = nullptr);
  /// Removes a call's engine viewer (when its first frame added one), in a
  /// pool job under `client`: its claims on its last PVS go with it, and the
  /// scene's lock is a job's to take, never a reaction's.
  void release_viewer(const std::string& client, const std::shared_ptr<SceneEntry>& e, const FrameViewer& viewer);
  /// Applies a move batch at time `t` to scene `e` (call from the scene's
  /// strand): the clock's step limit, the engine (errors on `field_prefix` +
  /// the engine's field, "batch.moves[3].id"), then the counters, the
  /// clocks, the metrics and the wake list.
  grpc::Status apply_batch(SceneEntry& e, double t, const std::vector<Move>& moves, const std::string& field_prefix,
                           MoveReport* report);
  /// Ends a unary call, counting an error.
  void finish_unary(UnaryCall* r, const char* method, const grpc::Status& s);
  /// Runs `f` (returns grpc::Status): the engine's part of a frame or a move
  /// batch of scene `e`. An exception it throws (a bug, or memory exhausted)
  /// becomes INTERNAL for this one call, logged with `what`; the process and
  /// every other call go on. With VOXVIS_TEST_FAIL_SCENE=<id> in the
  /// environment, every such call of scene <id> throws: the fault the
  /// tests inject to check this path (VOXVIS_TEST_FAIL_BUILD=<id> does the
  /// same to a build of scene <id>, after its grid is built).
  template <class F>
  grpc::Status guarded(const SceneEntry& e, const char* what, F&& f) {
    std::string text;
    try {
      if (!fail_scene_.empty() && e.id == fail_scene_)
        throw std::runtime_error("fault injected (VOXVIS_TEST_FAIL_SCENE)");
      return f();
    } catch (const std::exception& x) {
      text = x.what();
    } catch (...) {
      text = "an exception that is not a std::exception";
    }
    log_(std::string("internal error in a ") + what + " of scene '" + e.id + "': " + text);
    return grpc::Status(grpc::StatusCode::INTERNAL, std::string("internal error in the ") + what + ": " + text);
  }

 private:
  /// The scene, or null after finishing the call (INVALID_ARGUMENT for an
  /// invalid id, missing()'s status).
  std::shared_ptr<SceneEntry> find_or_finish(UnaryCall* r, const char* method,
                                             const std::string& id);
  void fill_info(const SceneEntry& e, v1::SceneInfo* out) const;

  ServiceConfig config_;
  WorkerPool& pool_;
  WorkerPool& builds_;
  const TokenTable& tokens_;
  Metrics& metrics_;
  SceneStore& store_;
  Log log_;
  Verifier* verifier_ = nullptr;
  const std::string fail_scene_;  // VOXVIS_TEST_FAIL_SCENE; empty: none.
  std::atomic<bool> stopping_{false};  // shutting_down_, readable without the lock.
  SceneRegistry registry_;

  mutable std::mutex misplaced_mu_;
  std::map<std::string, std::string> misplaced_;  // Guarded by misplaced_mu_: id -> owner.

  std::mutex streams_mu_;
  std::unordered_set<Stream*> streams_;  // Guarded by streams_mu_.
  bool shutting_down_ = false;           // Guarded by streams_mu_.
  std::atomic<std::uint64_t> dropped_{0};
  std::atomic<int> calls_{0};
};

}  // namespace voxvis::server
