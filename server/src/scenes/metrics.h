// metrics.h — Prometheus metrics for operators (prometheus-cpp, pull mode).
//
// Served at http://ADDR/metrics when the server runs with --metrics ADDR.
// Every family is labelled by scene ("scene") where it applies:
//   voxvis_frames_total{scene}                counter
//   voxvis_frame_latency_seconds{scene}       histogram: request received to answer handed to gRPC
//   voxvis_frame_engine_seconds{scene}        histogram: engine time of a frame
//   voxvis_pvs_size{scene}                    histogram: objects per PVS
//   voxvis_voxels_visited{scene}              histogram: voxels per frame
//   voxvis_frames_skipped_total{scene}        counter: requests replaced by newer ones
//   voxvis_moves_total{scene}                 counter: moves applied
//   voxvis_wake_size{scene}                   gauge: current wake-list size
//   voxvis_tbvs_active{scene}                 gauge
//   voxvis_viewers{scene}                     gauge: open viewer streams
//   voxvis_verify_frames_total{scene}         counter: served frames checked by --verify-fraction
//   voxvis_verify_missed_objects_total{scene} counter: visible objects missing from a checked PVS
//   voxvis_verify_edge_only_total{scene}      counter: objects missing from a checked PVS that EGL
//                                             showed only along an edge (not visible, not missed)
//   voxvis_verify_dropped_total{scene}        counter: frames sampled but not checked
//   voxvis_scenes                             gauge
//   voxvis_errors_total{method, code}         counter: calls ended with a non-OK status
//   process_cpu_seconds_total                 counter: the server's user + system CPU time
//   process_max_resident_memory_bytes         gauge: peak resident set size
#pragma once

#include <memory>
#include <string>

#include <grpcpp/grpcpp.h>

#include "voxvis/scene.h"

namespace voxvis::server {

/// Per-scene metric handles; cheap to use from any thread (prometheus-cpp
/// metrics are atomic).
class SceneMetrics {
 public:
  virtual ~SceneMetrics() = default;
  virtual void frame(const FrameStats& stats, double latency_seconds) = 0;
  /// CPU seconds a worker thread spent in a frame's engine call (what the
  /// server's CPU per answer subtracts: unlike FrameStats::time_us, it does
  /// not count time the thread waited for a core).
  virtual void engine_cpu(double seconds) = 0;
  /// Whether engine_cpu records anything (the caller then reads the clock).
  virtual bool wants_engine_cpu() const { return true; }
  virtual void skipped(std::uint32_t n) = 0;
  virtual void moves(std::uint32_t n) = 0;
  virtual void wake_size(std::size_t n) = 0;
  virtual void tbvs_active(std::uint32_t n) = 0;
  virtual void viewers(int delta) = 0;
  /// A served frame verified (verify mode), with its missed objects.
  virtual void verified(std::size_t missed) = 0;
  /// Objects of a verified frame missing from its PVS that EGL showed, but
  /// only along an edge (single precision; not visible, not missed).
  virtual void verify_edge_only(std::size_t n) = 0;
  /// A frame sampled for verification that could not be verified.
  virtual void verify_dropped() = 0;
};

class Metrics {
 public:
  virtual ~Metrics() = default;
  /// Handles for one scene; removed from the registry when the scene is
  /// deleted (remove_scene).
  virtual std::shared_ptr<SceneMetrics> scene(const std::string& scene_id) = 0;
  virtual void remove_scene(const std::string& scene_id) = 0;
  virtual void scenes(std::size_t n) = 0;
  /// Counts a call that ended with a non-OK status.
  virtual void error(const char* method, grpc::StatusCode code) = 0;
  /// The TCP port the metrics are served on (the one the system chose when
  /// ADDR asked for port 0); 0 when nothing is served.
  virtual int port() const { return 0; }
};

/// Handles that record nothing (no --metrics); a base for test doubles that
/// record only what they look at.
class NullSceneMetrics : public SceneMetrics {
 public:
  void frame(const FrameStats&, double) override {}
  void engine_cpu(double) override {}
  bool wants_engine_cpu() const override { return false; }
  void skipped(std::uint32_t) override {}
  void moves(std::uint32_t) override {}
  void wake_size(std::size_t) override {}
  void tbvs_active(std::uint32_t) override {}
  void viewers(int) override {}
  void verified(std::size_t) override {}
  void verify_edge_only(std::size_t) override {}
  void verify_dropped() override {}
};

/// CPU seconds the calling thread has used (CLOCK_THREAD_CPUTIME_ID).
double thread_cpu_seconds();

/// Metrics served over HTTP at `address` ("127.0.0.1:9464"). Throws
/// std::runtime_error naming the address when it cannot listen.
std::unique_ptr<Metrics> make_prometheus_metrics(const std::string& address);
/// Metrics that record nothing (no --metrics).
std::unique_ptr<Metrics> make_null_metrics();

}  // namespace voxvis::server
