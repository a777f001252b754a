#include "scenes/scene_entry.h"

#include <algorithm>
#include <cmath>
#include <utility>

#include "voxvis/assert.h"

namespace voxvis::server {
namespace {

/// Frames of one scene finish in any order: the statistic keeps the latest.
void store_max(std::atomic<double>& a, double v) {
  double cur = a.load(std::memory_order_relaxed);
  while (cur < v && !a.compare_exchange_weak(cur, v, std::memory_order_relaxed)) {
  }
}

}  // namespace

void SceneEntry::refresh_wake() {
  std::lock_guard<std::mutex> lock(wake_mu);
  // The epoch is read before the set: a change in between is seen again next
  // time, never lost.
  const std::uint64_t epoch = scene->wake_epoch();
  if (epoch == wake_epoch_seen && wake) return;
  wake_epoch_seen = epoch;
  // Into a reused buffer: the epoch moves with most frames of a scene with
  // dynamic objects, the set itself far less often.
  std::vector<ObjectId>& ids = wake_buffer;
  scene->wake_set(&ids);
  wake_size.store(static_cast<std::uint32_t>(ids.size()), std::memory_order_relaxed);
  if (metrics) metrics->wake_size(ids.size());
  if (wake && wake->ids == ids) return;
  auto snap = std::make_shared<WakeSnapshot>();
  snap->version = wake ? wake->version + 1 : 1;
  snap->ids = ids;
  wake = snap;
  for (const auto& sink : sinks) sink->wake_changed(wake);
}

void SceneEntry::after_frame(const FrameResult& result) {
  frames_served.fetch_add(1, std::memory_order_relaxed);
  tbvs_active.store(result.stats.tbvs_active, std::memory_order_relaxed);
  if (metrics) metrics->tbvs_active(result.stats.tbvs_active);
  store_max(time, result.t);
  refresh_wake();
}

void SceneEntry::after_moves(double at) {
  VOXVIS_ASSERT(strand && strand->runs_here());  // sim_clock_set is the strand's.
  store_max(time, at);
  store_max(sim_time, at);
  sim_clock_set = true;
}

double SceneEntry::view_time(double t, double lead) const {
  return std::fmin(t, sim_time.load(std::memory_order_relaxed) + lead);
}

void SceneEntry::subscribe(const std::shared_ptr<WakeSink>& sink) {
  refresh_wake();
  std::lock_guard<std::mutex> lock(wake_mu);
  sinks.push_back(sink);
  sink->wake_changed(wake);  // The whole list first.
}

void SceneEntry::unsubscribe(const std::shared_ptr<WakeSink>& sink) {
  std::lock_guard<std::mutex> lock(wake_mu);
  sinks.erase(std::remove(sinks.begin(), sinks.end(), sink), sinks.end());
}

}  // namespace voxvis::server
