// verifier.h — the server's verify mode (--verify-fraction): a sample of the
// frames served is rendered headlessly (render/) on a background thread with
// its own EGL context, and every visible object missing from the PVS that was
// served is counted in the metrics and logged with the scene, viewer, frame
// and camera, so that an operator can replay it (docs/server.md, "Verify
// mode"). As in `voxvis verify`, what EGL shows but the PVS lacks is a miss
// only when the double-precision ray caster confirms it near one of its
// pixels (raycast::confirm_near_pixels); the rest, seen in single precision
// along an edge only, is counted apart and not logged (docs/verify.md).
// The frame being served never waits for it: jobs are handed over
// after the answer, into a bounded queue; a full queue drops the job (counted).
#pragma once

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "scenes/metrics.h"
#include "voxvis/render.h"
#include "voxvis/scene.h"

namespace voxvis::server {

struct VerifyConfig {
  double fraction = 0.0;   ///< Of served frames, in [0, 1]; 0: off.
  int width = 320;         ///< Rendered pixels.
  int height = 180;
  std::size_t queue = 64;  ///< Jobs waiting at most; more are dropped.
  render::ContextOptions context;
};

/// A served frame to verify. `objects` are the scene's objects ascending by
/// id at the positions the frame saw.
struct VerifyJob {
  std::string scene;
  std::string viewer;     ///< Who asked (peer and stream) for the log.
  std::uint64_t frame = 0;
  double t = 0.0;
  Camera camera;
  std::vector<ObjectId> pvs;  ///< Ascending, as served.
  std::vector<ObjectDesc> objects;
  std::shared_ptr<SceneMetrics> metrics;
};

class Verifier {
 public:
  using Log = std::function<void(const std::string&)>;
  /// Starts the thread and its renderer; null with `error` when the renderer
  /// cannot be had (no EGL, ...) or the resolution exceeds its limit.
  static std::unique_ptr<Verifier> start(const VerifyConfig& config, Log log, std::string* error);
  ~Verifier();
  Verifier(const Verifier&) = delete;
  Verifier& operator=(const Verifier&) = delete;

  /// Whether the next served frame is one to verify: exactly `fraction` of
  /// the calls, spread evenly. Thread-safe.
  bool sample();
  /// Queues a job, or drops it (counted) when the queue is full. Never blocks
  /// on rendering.
  void submit(VerifyJob job);
  /// Counts a sampled frame that could not be handed over.
  void dropped(SceneMetrics* metrics);
  /// Waits until every queued job is done (tests, shutdown).
  void drain();
  const render::ContextInfo& renderer_info() const { return info_; }

  /// Totals since start.
  struct Totals {
    std::uint64_t verified = 0, frames_missed = 0, objects_missed = 0, dropped = 0;
    std::uint64_t edge_only = 0;  ///< Sightings dismissed: EGL's single precision along an edge.
  };
  Totals totals() const;

 private:
  Verifier(const VerifyConfig& config, Log log) : config_(config), log_(std::move(log)) {}
  void run(std::string* start_error, bool* started);
  void verify(VerifyJob& job, render::Renderer& r);

  VerifyConfig config_;
  Log log_;
  render::ContextInfo info_;
  std::thread thread_;
  mutable std::mutex mu_;
  std::condition_variable cv_;
  std::deque<VerifyJob> queue_;  // Guarded by mu_.
  bool busy_ = false;            // Guarded by mu_.
  bool stop_ = false;            // Guarded by mu_.
  Totals totals_;                // Guarded by mu_.
  std::uint64_t calls_ = 0;      // Guarded by mu_.
};

/// The objects of a scene at the positions of `centers` (ascending ids):
/// `objects` (ascending ids) with the dynamic ones' centres replaced, and a
/// mesh's rotation too when its move has one.
std::vector<ObjectDesc> objects_at(const std::vector<ObjectDesc>& objects, const std::vector<Move>& centers);

}  // namespace voxvis::server
