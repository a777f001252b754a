// scene_entry.h — a scene being served: the engine's Scene and what the
// server keeps beside it (its strand, clocks, counters, metrics, and the wake
// list it hands to Simulate and Tick streams). The scenes themselves are kept by the
// SceneRegistry (scene_registry.h).
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "scenes/metrics.h"
#include "scenes/pool.h"
#include "voxvis/scene.h"

namespace voxvis::server {

/// The wake list at one moment: ascending ids, and a version that increases
/// with every change.
struct WakeSnapshot {
  std::uint64_t version = 0;
  std::vector<ObjectId> ids;
};

/// Where a scene delivers its wake list's changes: every Simulate and Tick
/// stream subscribes one (SceneEntry::subscribe; StreamWakeSink in
/// stream_reactor.h implements it) and the scene calls it, under its
/// wake_mu, with the whole list first and then every new one. The scene
/// knows only this interface, never the streams.
class WakeSink {
 public:
  virtual ~WakeSink() = default;
  virtual void wake_changed(std::shared_ptr<const WakeSnapshot> snap) = 0;
};

/// The engine's viewer of a call that keeps one across frames (a View
/// stream's, each viewer of a Tick stream), added by its first frame
/// (Serving::serve_frame).
struct FrameViewer {
  bool added = false;  ///< The engine's viewer exists.
  ViewerId id = 0;
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
  std::uint64_t memory_bytes = 0;  ///< Reserved in the budget: SceneCost::served_bytes.
  GridSpec grid;  // Immutable copies for statistics.
  std::uint32_t objects = 0;
  std::uint32_t dynamic_objects = 0;
  std::uint32_t mesh_objects = 0;
  std::uint64_t mesh_triangles = 0;  ///< Of its distinct meshes.

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
  std::vector<ObjectId> wake_buffer;                       // Guarded by wake_mu: refresh_wake's.
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
  /// hands a new snapshot to every sink subscribed (Simulate and Tick streams).
  void refresh_wake();
  /// Registers a stream's sink and hands it the whole list.
  void subscribe(const std::shared_ptr<WakeSink>& sink);
  void unsubscribe(const std::shared_ptr<WakeSink>& sink);
};

}  // namespace voxvis::server
