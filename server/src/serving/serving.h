// serving.h — what a call does to a scene once admitted (admission.h): find
// it, serve a frame of it (GetPvs, View and Tick alike), apply a move batch
// to it, release a call's engine viewer, and hand served frames to verify
// mode. The engine's part of each runs guarded: an exception becomes
// INTERNAL for that one call.
#pragma once

#include <functional>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include <grpcpp/grpcpp.h>

#include "scenes/pool.h"
#include "scenes/scene_entry.h"
#include "scenes/scene_registry.h"
#include "scenes/verifier.h"
#include "serving/service_config.h"
#include "voxvis/scene.h"

namespace voxvis::server {

class Serving {
 public:
  using Log = std::function<void(const std::string&)>;
  /// `pool` runs frames and move batches; `registry` keeps the scenes.
  Serving(const ServiceConfig& config, WorkerPool& pool, SceneRegistry& registry, Log log);
  Serving(const Serving&) = delete;
  Serving& operator=(const Serving&) = delete;

  /// The scene, or null.
  std::shared_ptr<SceneEntry> find(const std::string& id) const { return registry_.find(id); }
  /// The status of a call on a scene this server does not have: the shard
  /// identity's refusal naming the owner when the id is another shard's,
  /// else NOT_FOUND.
  grpc::Status missing(const std::string& id) const;
  WorkerPool& pool() { return pool_; }

  /// Serves one frame of scene `e`, in a pool job. NOT_FOUND when the scene
  /// was deleted; else the frame of `viewer` (added by its first frame;
  /// null: a viewer for this frame only) at `t` as the scene's clock allows
  /// (SceneEntry::view_time), run by guarded() into `*result`, then the
  /// scene's bookkeeping (SceneEntry::after_frame). `*check`, when given,
  /// says whether verify mode samples the frame: the caller hands it to
  /// verify_served after its answer. The answer itself is answer_frame's
  /// (frame_answer.h), when the call writes it.
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

  /// Verify mode (--verify-fraction): set before serving; null when off.
  void set_verifier(Verifier* v);
  /// Hands a served frame to the verifier, after its answer: reads the
  /// dynamic objects' positions, which must still be those the frame saw
  /// (FrameResult::positions_epoch), else the frame is dropped (counted).
  void verify_served(const SceneEntry& e, const std::string& viewer, std::uint64_t frame, const Camera& camera,
                     const FrameResult& result);

 private:
  /// Runs `f` (returns grpc::Status): the engine's part of a frame or a move
  /// batch of scene `e`. An exception it throws (a bug, or memory exhausted)
  /// becomes INTERNAL for this one call, logged with `what`; the process and
  /// every other call go on. With VOXVIS_TEST_FAIL_SCENE=<id> in the
  /// environment, every such call of scene <id> throws: the fault the
  /// tests inject to check this path (VOXVIS_TEST_FAIL_BUILD=<id> does the
  /// same to a build of scene <id>, after its grid is built).
  template <class F>
  grpc::Status guarded(const SceneEntry& e, const char* what, F&& f);

  /// Whether the frame about to be served is one to verify.
  bool verify_sample() { return verifier_ != nullptr && verifier_->sample(); }

  const ServiceConfig& config_;
  WorkerPool& pool_;
  SceneRegistry& registry_;
  Log log_;
  Verifier* verifier_ = nullptr;
  const std::string fail_scene_;  // VOXVIS_TEST_FAIL_SCENE; empty: none.
};

template <class F>
grpc::Status Serving::guarded(const SceneEntry& e, const char* what, F&& f) {
  std::string text;
  try {
    if (!fail_scene_.empty() && e.id == fail_scene_) throw std::runtime_error("fault injected (VOXVIS_TEST_FAIL_SCENE)");
    return f();
  } catch (const std::exception& x) {
    text = x.what();
  } catch (...) {
    text = "an exception that is not a std::exception";
  }
  log_(std::string("internal error in a ") + what + " of scene '" + e.id + "': " + text);
  return grpc::Status(grpc::StatusCode::INTERNAL, std::string("internal error in the ") + what + ": " + text);
}

}  // namespace voxvis::server
