// service.h — the Visibility service (proto/voxvis/v1/voxvis.proto) on gRPC's
// callback API, and the scenes it serves.
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
#include <set>
#include <stdexcept>
#include <string>
#include <unordered_set>
#include <vector>

#include <grpcpp/grpcpp.h>

#include "auth.h"
#include "calls.h"
#include "metrics.h"
#include "pool.h"
#include "store.h"
#include "verifier.h"
#include "voxvis/scene.h"
#include "voxvis/v1/voxvis.grpc.pb.h"

namespace voxvis::server {

/// The wake list at one moment: ascending ids, and a version that increases
/// with every change.
struct WakeSnapshot {
  std::uint64_t version = 0;
  std::vector<ObjectId> ids;
};

class SimReactor;

/// Where a scene delivers wake-list changes to one Simulate stream. The
/// stream clears `reactor` (under `mu`) before it is deleted.
struct WakeSink {
  std::mutex mu;
  SimReactor* reactor = nullptr;  // Guarded by mu.
};

/// A scene being served. The Scene synchronizes itself: frames of different
/// viewers run in parallel, moves exclusively (voxvis/scene.h). Move batches
/// go through `strand`, so that a scene's batches apply in arrival order and
/// occupy one worker at a time.
struct SceneEntry {
  std::string id;
  std::shared_ptr<Strand> strand;
  std::unique_ptr<Scene> scene;
  std::shared_ptr<SceneMetrics> metrics;
  std::uint64_t memory_bytes = 0;  ///< Reserved in the budget: Scene::estimate's bytes and scratch.
  GridSpec grid;  // Immutable copies for statistics.
  std::uint32_t objects = 0;
  std::uint32_t dynamic_objects = 0;

  std::atomic<bool> deleted{false};
  std::atomic<bool> positions_dirty{false};
  std::atomic<std::uint64_t> frames_served{0};
  std::atomic<std::uint64_t> moves_applied{0};
  std::atomic<std::uint32_t> viewers{0};
  std::atomic<std::uint32_t> simulators{0};
  std::atomic<std::uint32_t> tbvs_active{0};
  std::atomic<std::uint32_t> wake_size{0};
  std::atomic<double> time{0.0};
  /// The clock as the simulation set it: the latest batch time (or the saved
  /// time at load). Viewers' frames may run at most ServiceConfig's
  /// max_view_lead_s beyond it. Written by the scene's strand only.
  std::atomic<double> sim_time{0.0};
  /// Verify mode only: the scene's objects as created, ascending ids (the
  /// static ones never move; dynamic centres come from the scene).
  std::shared_ptr<const std::vector<ObjectDesc>> verify_objects;
  /// Whether any simulation batch (or a saved time) has set the clock yet;
  /// the first may set it anywhere in range. Touched by the strand only.
  bool sim_clock_set = false;

  std::mutex wake_mu;
  std::uint64_t wake_epoch_seen = ~std::uint64_t{0};       // Guarded by wake_mu.
  std::shared_ptr<const WakeSnapshot> wake;                // Guarded by wake_mu.
  std::vector<std::shared_ptr<WakeSink>> sinks;            // Guarded by wake_mu.

  /// Bookkeeping after a frame computed for any viewer: counters, metrics,
  /// the scene's time and the wake list.
  void after_frame(const FrameResult& result);
  /// Bookkeeping after a simulation batch applied at scene time `at`: the
  /// scene's and the simulation's clocks. Called by the scene's strand.
  void after_moves(double at);
  /// The time a viewer's frame at `t` runs at: `t`, but at most `lead`
  /// seconds beyond the simulation's clock (viewers do not own the clock).
  double view_time(double t, double lead) const;
  /// Recomputes the wake list when the engine says it may have changed and
  /// hands a new snapshot to every Simulate stream of the scene.
  void refresh_wake();
  /// Registers a Simulate stream's sink and hands it the whole list.
  void subscribe(const std::shared_ptr<WakeSink>& sink);
  void unsubscribe(const std::shared_ptr<WakeSink>& sink);
};

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
                            v1::Visibility::WithRawCallbackMethod_GetPvs<v1::Visibility::Service>>>>>>>>;

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
  /// given, replace the centres of the dynamic objects they name.
  Status load_scene(const std::string& id, const std::string& json, const std::string& source,
                    const std::vector<Move>* positions, std::optional<double> t, bool persist);
  bool has_scene(const std::string& id) const;

  /// Ends every stream with UNAVAILABLE after its in-flight frame and refuses
  /// new ones. Call before grpc::Server::Shutdown.
  void begin_shutdown();
  /// Writes the positions of every scene whose dynamic objects moved since
  /// the last save.
  void save_positions();

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

  // For the reactors.
  std::shared_ptr<SceneEntry> find(const std::string& id) const;
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
  void set_verifier(Verifier* v) { verifier_ = v; }
  /// Whether the frame about to be served is one to verify.
  bool verify_sample() { return verifier_ != nullptr && verifier_->sample(); }
  /// Hands a served frame to the verifier, after its answer: reads the
  /// dynamic objects' positions, which must still be those the frame saw
  /// (FrameResult::positions_epoch), else the frame is dropped (counted).
  void verify_served(const SceneEntry& e, const std::string& viewer, std::uint64_t frame, const Camera& camera,
                     const FrameResult& result);
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
  /// invalid id, NOT_FOUND).
  std::shared_ptr<SceneEntry> find_or_finish(UnaryCall* r, const char* method,
                                             const std::string& id);
  void fill_info(const SceneEntry& e, v1::SceneInfo* out) const;
  /// Checks the budget, builds, persists (when `persist`) and registers a
  /// scene. INVALID_ARGUMENT, ALREADY_EXISTS, RESOURCE_EXHAUSTED or INTERNAL.
  /// The cost comes from Scene::estimate (the objects' footprints) before
  /// anything large is allocated; `control` (may be null) cancels the build
  /// (CANCELLED, or UNAVAILABLE when the server is stopping).
  grpc::Status build_scene(const std::string& id, SceneDesc desc, const std::string& json,
                           bool from_json, bool persist, const BuildControl* control = nullptr);
  /// OK when no scene has or is taking the id: else ALREADY_EXISTS, or
  /// ABORTED while it is being deleted.
  grpc::Status id_free_locked(const std::string& id) const;

  ServiceConfig config_;
  WorkerPool& pool_;
  WorkerPool& builds_;
  SceneStore& store_;
  const TokenTable& tokens_;
  Metrics& metrics_;
  Log log_;
  Verifier* verifier_ = nullptr;
  const std::string fail_scene_;  // VOXVIS_TEST_FAIL_SCENE; empty: none.
  const std::string fail_build_;  // VOXVIS_TEST_FAIL_BUILD: builds of that id throw once built.

  mutable std::mutex scenes_mu_;
  std::map<std::string, std::shared_ptr<SceneEntry>> scenes_;  // Guarded by scenes_mu_.
  std::map<std::string, std::uint64_t> reserved_;  // Guarded by scenes_mu_: ids being created.
  std::set<std::string> deleting_;                 // Guarded by scenes_mu_: ids being deleted.
  std::uint64_t bytes_in_use_ = 0;                 // Guarded by scenes_mu_ (scenes and reserved).

  std::mutex store_mu_;  // Serializes position saves with scene deletion.

  std::mutex streams_mu_;
  std::unordered_set<Stream*> streams_;  // Guarded by streams_mu_.
  bool shutting_down_ = false;           // Guarded by streams_mu_.
  std::atomic<bool> stopping_{false};    // shutting_down_, readable without the lock.
  std::atomic<std::uint64_t> dropped_{0};
  std::atomic<int> calls_{0};
};

}  // namespace voxvis::server
