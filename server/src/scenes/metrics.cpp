// metrics.cpp — prometheus-cpp families, the HTTP exposer, and null metrics.
#include "scenes/metrics.h"

#include <map>
#include <mutex>
#include <shared_mutex>
#include <stdexcept>
#include <utility>
#include <vector>

#include <sys/resource.h>
#include <time.h>

#include <prometheus/collectable.h>
#include <prometheus/counter.h>
#include <prometheus/exposer.h>
#include <prometheus/family.h>
#include <prometheus/gauge.h>
#include <prometheus/histogram.h>
#include <prometheus/metric_family.h>
#include <prometheus/registry.h>

namespace voxvis::server {
namespace {

using prometheus::Counter;
using prometheus::Family;
using prometheus::Gauge;
using prometheus::Histogram;

// Bucket bounds step 1-2-5 per decade: roughly exponential, and written as
// literals so that the exported "le" labels are the round numbers shown here
// rather than accumulated floating-point products.
const Histogram::BucketBoundaries kLatencyBuckets = {  // seconds, 50 µs .. 1 s
    50e-6, 100e-6, 200e-6, 500e-6, 1e-3, 2e-3, 5e-3, 10e-3, 20e-3, 50e-3, 0.1, 0.2, 0.5, 1.0};
const Histogram::BucketBoundaries kPvsBuckets = {  // objects, 1 .. 100k
    1, 2, 5, 10, 20, 50, 100, 200, 500, 1e3, 2e3, 5e3, 1e4, 2e4, 5e4, 1e5};
const Histogram::BucketBoundaries kVoxelBuckets = {  // voxels, 1k .. 10M
    1e3, 2e3, 5e3, 1e4, 2e4, 5e4, 1e5, 2e5, 5e5, 1e6, 2e6, 5e6, 1e7};

const char* code_name(grpc::StatusCode code) {
  switch (code) {
    case grpc::StatusCode::OK: return "OK";
    case grpc::StatusCode::CANCELLED: return "CANCELLED";
    case grpc::StatusCode::UNKNOWN: return "UNKNOWN";
    case grpc::StatusCode::INVALID_ARGUMENT: return "INVALID_ARGUMENT";
    case grpc::StatusCode::DEADLINE_EXCEEDED: return "DEADLINE_EXCEEDED";
    case grpc::StatusCode::NOT_FOUND: return "NOT_FOUND";
    case grpc::StatusCode::ALREADY_EXISTS: return "ALREADY_EXISTS";
    case grpc::StatusCode::PERMISSION_DENIED: return "PERMISSION_DENIED";
    case grpc::StatusCode::UNAUTHENTICATED: return "UNAUTHENTICATED";
    case grpc::StatusCode::RESOURCE_EXHAUSTED: return "RESOURCE_EXHAUSTED";
    case grpc::StatusCode::FAILED_PRECONDITION: return "FAILED_PRECONDITION";
    case grpc::StatusCode::ABORTED: return "ABORTED";
    case grpc::StatusCode::OUT_OF_RANGE: return "OUT_OF_RANGE";
    case grpc::StatusCode::UNIMPLEMENTED: return "UNIMPLEMENTED";
    case grpc::StatusCode::INTERNAL: return "INTERNAL";
    case grpc::StatusCode::UNAVAILABLE: return "UNAVAILABLE";
    case grpc::StatusCode::DATA_LOSS: return "DATA_LOSS";
    default: return "UNKNOWN_CODE";
  }
}

/// Every family, created once; owned by the registry.
struct Families {
  explicit Families(prometheus::Registry& r)
      : frames(prometheus::BuildCounter()
                   .Name("voxvis_frames_total")
                   .Help("Frames computed")
                   .Register(r)),
        latency(prometheus::BuildHistogram()
                    .Name("voxvis_frame_latency_seconds")
                    .Help("Seconds from a frame request received to its answer handed to gRPC")
                    .Register(r)),
        engine(prometheus::BuildHistogram()
                   .Name("voxvis_frame_engine_seconds")
                   .Help("Seconds of engine time per frame")
                   .Register(r)),
        engine_cpu(prometheus::BuildCounter()
                       .Name("voxvis_frame_engine_cpu_seconds_total")
                       .Help("CPU seconds worker threads spent in frames' engine calls")
                       .Register(r)),
        pvs(prometheus::BuildHistogram()
                .Name("voxvis_pvs_size")
                .Help("Objects per potentially visible set")
                .Register(r)),
        voxels(prometheus::BuildHistogram()
                   .Name("voxvis_voxels_visited")
                   .Help("Voxels visited per frame")
                   .Register(r)),
        skipped(prometheus::BuildCounter()
                    .Name("voxvis_frames_skipped_total")
                    .Help("Frame requests replaced by newer ones before being computed")
                    .Register(r)),
        moves(prometheus::BuildCounter()
                  .Name("voxvis_moves_total")
                  .Help("Object moves applied")
                  .Register(r)),
        wake(prometheus::BuildGauge()
                 .Name("voxvis_wake_size")
                 .Help("Current wake-list size (dynamic objects needing fresh positions)")
                 .Register(r)),
        tbvs(prometheus::BuildGauge()
                 .Name("voxvis_tbvs_active")
                 .Help("Temporal bounding volumes alive")
                 .Register(r)),
        viewers(prometheus::BuildGauge()
                    .Name("voxvis_viewers")
                    .Help("Open viewer streams")
                    .Register(r)),
        scenes(prometheus::BuildGauge().Name("voxvis_scenes").Help("Scenes loaded").Register(r)),
        verified(prometheus::BuildCounter()
                     .Name("voxvis_verify_frames_total")
                     .Help("Served frames rendered and checked by the verify mode")
                     .Register(r)),
        verify_missed(prometheus::BuildCounter()
                          .Name("voxvis_verify_missed_objects_total")
                          .Help("Visible objects missing from a verified frame's PVS (should stay 0)")
                          .Register(r)),
        verify_edge_only(prometheus::BuildCounter()
                             .Name("voxvis_verify_edge_only_total")
                             .Help("Objects missing from a verified frame's PVS that EGL showed only along an "
                                   "edge, in single precision: not visible, not counted as missed")
                             .Register(r)),
        verify_dropped(prometheus::BuildCounter()
                           .Name("voxvis_verify_dropped_total")
                           .Help("Frames sampled for verification but not verified (queue full, or "
                                 "objects moved before their positions were read)")
                           .Register(r)),
        errors(prometheus::BuildCounter()
                   .Name("voxvis_errors_total")
                   .Help("Calls that ended with a non-OK status, by method and status code")
                   .Register(r)) {}

  Family<Counter>& frames;
  Family<Histogram>& latency;
  Family<Histogram>& engine;
  Family<Counter>& engine_cpu;
  Family<Histogram>& pvs;
  Family<Histogram>& voxels;
  Family<Counter>& skipped;
  Family<Counter>& moves;
  Family<Gauge>& wake;
  Family<Gauge>& tbvs;
  Family<Gauge>& viewers;
  Family<Gauge>& scenes;
  Family<Counter>& verified;
  Family<Counter>& verify_missed;
  Family<Counter>& verify_edge_only;
  Family<Counter>& verify_dropped;
  Family<Counter>& errors;
};

/// Everything the handles and the exposer share. Held by shared_ptr so that a
/// SceneMetrics handle outliving the Metrics object still points at live
/// families.
struct State {
  std::shared_ptr<prometheus::Registry> registry = std::make_shared<prometheus::Registry>();
  Families families{*registry};
};

/// The process's own CPU time and peak memory, read at each scrape
/// (getrusage), under the names Prometheus' client libraries use for them.
/// CPU seconds over answers served is the server's cost per answer
/// (`voxvis loadgen --metrics` reports it; docs/performance.md).
class ProcessCollector final : public prometheus::Collectable {
 public:
  std::vector<prometheus::MetricFamily> Collect() const override {
    rusage usage{};
    if (getrusage(RUSAGE_SELF, &usage) != 0) return {};
    const auto seconds = [](const timeval& tv) {
      return static_cast<double>(tv.tv_sec) + 1e-6 * static_cast<double>(tv.tv_usec);
    };
    std::vector<prometheus::MetricFamily> out(2);
    out[0].name = "process_cpu_seconds_total";
    out[0].help = "Total user and system CPU time spent in seconds";
    out[0].type = prometheus::MetricType::Counter;
    out[0].metric.emplace_back().counter.value = seconds(usage.ru_utime) + seconds(usage.ru_stime);
    out[1].name = "process_max_resident_memory_bytes";
    out[1].help = "Peak resident set size in bytes";
    out[1].type = prometheus::MetricType::Gauge;
    out[1].metric.emplace_back().gauge.value = 1024.0 * static_cast<double>(usage.ru_maxrss);  // KiB on Linux.
    return out;
  }
};

class PrometheusSceneMetrics final : public SceneMetrics {
 public:
  PrometheusSceneMetrics(std::shared_ptr<State> state, const std::string& scene_id)
      : state_(std::move(state)) {
    Families& f = state_->families;
    const prometheus::Labels labels{{"scene", scene_id}};
    frames_ = &f.frames.Add(labels);
    latency_ = &f.latency.Add(labels, kLatencyBuckets);
    engine_ = &f.engine.Add(labels, kLatencyBuckets);
    engine_cpu_ = &f.engine_cpu.Add(labels);
    pvs_ = &f.pvs.Add(labels, kPvsBuckets);
    voxels_ = &f.voxels.Add(labels, kVoxelBuckets);
    skipped_ = &f.skipped.Add(labels);
    moves_ = &f.moves.Add(labels);
    wake_ = &f.wake.Add(labels);
    tbvs_ = &f.tbvs.Add(labels);
    viewers_ = &f.viewers.Add(labels);
    verified_ = &f.verified.Add(labels);
    verify_missed_ = &f.verify_missed.Add(labels);
    verify_edge_only_ = &f.verify_edge_only.Add(labels);
    verify_dropped_ = &f.verify_dropped.Add(labels);
  }

  /// Family::Remove destroys the metric objects, while callers may still hold
  /// this handle and record from other threads. The shared lock in every
  /// recording method and the `removed_` flag turn such late calls into
  /// no-ops instead of use-after-free; the lock is uncontended except here.
  void detach() {
    std::unique_lock lock(mutex_);
    if (removed_) return;
    removed_ = true;
    Families& f = state_->families;
    f.frames.Remove(frames_);
    f.latency.Remove(latency_);
    f.engine.Remove(engine_);
    f.engine_cpu.Remove(engine_cpu_);
    f.pvs.Remove(pvs_);
    f.voxels.Remove(voxels_);
    f.skipped.Remove(skipped_);
    f.moves.Remove(moves_);
    f.wake.Remove(wake_);
    f.tbvs.Remove(tbvs_);
    f.viewers.Remove(viewers_);
    f.verified.Remove(verified_);
    f.verify_missed.Remove(verify_missed_);
    f.verify_edge_only.Remove(verify_edge_only_);
    f.verify_dropped.Remove(verify_dropped_);
  }

  void frame(const FrameStats& stats, double latency_seconds) override {
    std::shared_lock lock(mutex_);
    if (removed_) return;
    frames_->Increment();
    latency_->Observe(latency_seconds);
    engine_->Observe(stats.time_us * 1e-6);
    pvs_->Observe(static_cast<double>(stats.pvs_size));
    voxels_->Observe(static_cast<double>(stats.voxels_visited));
  }
  void engine_cpu(double seconds) override {
    std::shared_lock lock(mutex_);
    if (!removed_ && seconds > 0.0) engine_cpu_->Increment(seconds);
  }
  void skipped(std::uint32_t n) override {
    std::shared_lock lock(mutex_);
    if (!removed_ && n > 0) skipped_->Increment(static_cast<double>(n));
  }
  void moves(std::uint32_t n) override {
    std::shared_lock lock(mutex_);
    if (!removed_ && n > 0) moves_->Increment(static_cast<double>(n));
  }
  void wake_size(std::size_t n) override {
    std::shared_lock lock(mutex_);
    if (!removed_) wake_->Set(static_cast<double>(n));
  }
  void tbvs_active(std::uint32_t n) override {
    std::shared_lock lock(mutex_);
    if (!removed_) tbvs_->Set(static_cast<double>(n));
  }
  void viewers(int delta) override {
    std::shared_lock lock(mutex_);
    if (removed_) return;
    // Increment/Decrement are atomic read-modify-writes; Set would lose
    // concurrent opens and closes.
    if (delta > 0) viewers_->Increment(static_cast<double>(delta));
    if (delta < 0) viewers_->Decrement(-static_cast<double>(delta));
  }
  void verified(std::size_t missed) override {
    std::shared_lock lock(mutex_);
    if (removed_) return;
    verified_->Increment();
    if (missed > 0) verify_missed_->Increment(static_cast<double>(missed));
  }
  void verify_edge_only(std::size_t n) override {
    std::shared_lock lock(mutex_);
    if (!removed_ && n > 0) verify_edge_only_->Increment(static_cast<double>(n));
  }
  void verify_dropped() override {
    std::shared_lock lock(mutex_);
    if (!removed_) verify_dropped_->Increment();
  }

 private:
  std::shared_ptr<State> state_;
  std::shared_mutex mutex_;
  bool removed_ = false;
  Counter* frames_;
  Histogram* latency_;
  Histogram* engine_;
  Counter* engine_cpu_;
  Histogram* pvs_;
  Histogram* voxels_;
  Counter* skipped_;
  Counter* moves_;
  Gauge* wake_;
  Gauge* tbvs_;
  Gauge* viewers_;
  Counter* verified_;
  Counter* verify_missed_;
  Counter* verify_edge_only_;
  Counter* verify_dropped_;
};

class PrometheusMetrics final : public Metrics {
 public:
  explicit PrometheusMetrics(const std::string& address) {
    try {
      exposer_ = std::make_unique<prometheus::Exposer>(address);
    } catch (const std::exception& e) {
      // civetweb's exception says only "null context ... binding to port".
      throw std::runtime_error("cannot serve metrics on " + address + ": " + e.what());
    }
    const std::vector<int> ports = exposer_->GetListeningPorts();
    port_ = ports.empty() ? 0 : ports.front();
    scenes_ = &state_->families.scenes.Add({});
    exposer_->RegisterCollectable(state_->registry);
    exposer_->RegisterCollectable(process_);
  }

  std::shared_ptr<SceneMetrics> scene(const std::string& scene_id) override {
    std::lock_guard lock(mutex_);
    // One handle per scene: Family::Add would hand back the same metrics for
    // the same labels anyway, and remove_scene must reach every holder.
    auto& handle = scenes_by_id_[scene_id];
    if (!handle) handle = std::make_shared<PrometheusSceneMetrics>(state_, scene_id);
    return handle;
  }

  void remove_scene(const std::string& scene_id) override {
    std::shared_ptr<PrometheusSceneMetrics> handle;
    {
      std::lock_guard lock(mutex_);
      const auto it = scenes_by_id_.find(scene_id);
      if (it == scenes_by_id_.end()) return;
      handle = std::move(it->second);
      scenes_by_id_.erase(it);
    }
    handle->detach();
  }

  void scenes(std::size_t n) override { scenes_->Set(static_cast<double>(n)); }

  void error(const char* method, grpc::StatusCode code) override {
    state_->families.errors.Add({{"method", method}, {"code", code_name(code)}}).Increment();
  }

  int port() const override { return port_; }

 private:
  std::shared_ptr<State> state_ = std::make_shared<State>();
  std::shared_ptr<ProcessCollector> process_ = std::make_shared<ProcessCollector>();
  // Declared after state_ and process_ so that it is destroyed first: no scrape can run
  // while the families go away.
  std::unique_ptr<prometheus::Exposer> exposer_;
  int port_ = 0;
  Gauge* scenes_ = nullptr;
  std::mutex mutex_;
  std::map<std::string, std::shared_ptr<PrometheusSceneMetrics>> scenes_by_id_;
};

class NullMetrics final : public Metrics {
 public:
  std::shared_ptr<SceneMetrics> scene(const std::string&) override { return handle_; }
  void remove_scene(const std::string&) override {}
  void scenes(std::size_t) override {}
  void error(const char*, grpc::StatusCode) override {}

 private:
  std::shared_ptr<SceneMetrics> handle_ = std::make_shared<NullSceneMetrics>();
};

}  // namespace

double thread_cpu_seconds() {
  timespec ts{};
  if (clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts) != 0) return 0.0;
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

std::unique_ptr<Metrics> make_prometheus_metrics(const std::string& address) {
  return std::make_unique<PrometheusMetrics>(address);
}

std::unique_ptr<Metrics> make_null_metrics() { return std::make_unique<NullMetrics>(); }

}  // namespace voxvis::server
