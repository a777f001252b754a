// loadgen_cmd.cpp — `voxvis loadgen`: many concurrent viewers against one
// scene, for capacity and latency measurements.
//
// Design choices:
//  * gRPC's callback API: one ClientBidiReactor per viewer, no thread per
//    viewer. Reads run inside the reactions (each answer starts the next
//    read); writes come from the single pacing thread (this function's
//    thread), which holds each stream open with a hold (AddHold) until it
//    has sent its last write and WritesDone.
//  * At most one write outstanding per stream. A tick that finds the previous
//    write still outstanding is skipped and counted ("send skipped"): the
//    client, not the server, is then the bottleneck, and queueing more writes
//    would only measure the client's buffers.
//  * Viewers are spread evenly over each tick period, so the server sees a
//    steady load rather than N requests at once every tick.
//  * Latencies go into a log histogram (1% buckets) instead of a list, so a
//    long run takes constant memory; percentiles are exact to within 1%.
#include <algorithm>
#include <array>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <cstring>
#include <deque>
#include <fstream>
#include <map>
#include <memory>
#include <mutex>
#include <numbers>
#include <string>
#include <thread>
#include <vector>

#include <unistd.h>

#include <nlohmann/json.hpp>

#include "cli.h"
#include "common.h"
#include "output_file.h"
#include "voxvis/client.h"
#include "voxvis/format.h"

namespace voxvis::cli {
namespace {

using Clock = std::chrono::steady_clock;

/// Latencies in 1% wide logarithmic buckets from 1 us to about 1000 s;
/// updated concurrently by the reactions.
class Histogram {
 public:
  void add(double us) {
    std::size_t i = 0;
    if (us >= 1.0) {
      i = 1 + static_cast<std::size_t>(std::log(us) / kLogStep);
      i = std::min(i, kBuckets - 1);
    }
    counts_[i].fetch_add(1, std::memory_order_relaxed);
    total_.fetch_add(1, std::memory_order_relaxed);
    double prev = max_us_.load(std::memory_order_relaxed);
    while (us > prev && !max_us_.compare_exchange_weak(prev, us, std::memory_order_relaxed)) {
    }
  }
  std::uint64_t count() const { return total_.load(std::memory_order_relaxed); }
  double max_us() const { return max_us_.load(std::memory_order_relaxed); }
  /// Nearest-rank percentile, as the upper edge of its bucket (capped at the
  /// maximum), microseconds; 0 without samples.
  double percentile_us(double p) const {
    std::uint64_t n = 0;
    std::array<std::uint64_t, kBuckets> snapshot{};
    for (std::size_t i = 0; i < kBuckets; ++i) {
      snapshot[i] = counts_[i].load(std::memory_order_relaxed);
      n += snapshot[i];
    }
    if (n == 0) return 0.0;
    const auto rank = static_cast<std::uint64_t>(
        std::max(1.0, std::ceil(p / 100.0 * static_cast<double>(n))));
    std::uint64_t seen = 0;
    for (std::size_t i = 0; i < kBuckets; ++i) {
      seen += snapshot[i];
      if (seen >= rank) {
        const double upper = i == 0 ? 1.0 : std::exp(static_cast<double>(i) * kLogStep);
        return std::min(upper, max_us());
      }
    }
    return max_us();
  }

 private:
  static constexpr std::size_t kBuckets = 2100;
  static constexpr double kLogStep = 0.00995033085316808;  // ln(1.01)
  std::array<std::atomic<std::uint64_t>, kBuckets> counts_{};
  std::atomic<std::uint64_t> total_{0};
  std::atomic<double> max_us_{0.0};
};

/// State shared by all viewers and the pacing thread.
struct Shared {
  Histogram latency;
  Histogram first_answer;  ///< From a stream's first send to its first answer.
  Histogram gap;           ///< Between two answers of one stream (and before the first).
  std::atomic<std::uint64_t> frames{0};          ///< Answers received.
  std::atomic<std::uint64_t> server_skipped{0};  ///< Sum of frames_skipped.
  std::atomic<std::uint64_t> send_skipped{0};
  std::atomic<int> open{0};                      ///< Streams not yet done.
  Clock::time_point start;                       ///< Set before any stream starts.
  std::atomic<std::int64_t> last_answer_ns{0};   ///< Latest answer, ns after start.
  std::string address;                           ///< Server, for messages.

  std::mutex mu;
  std::condition_variable cv;
  int done = 0;                              // Guarded by mu.
  std::map<std::string, int> errors;         // Status code name -> streams; guarded by mu.
  int cancelled_at_end = 0;                  // Guarded by mu.
  std::string first_error;                   // Guarded by mu.
};

/// One viewer: a View stream driven by the pacing thread.
class Viewer final : public grpc::ClientBidiReactor<v1::ViewRequest, v1::ViewResponse> {
 public:
  Viewer(int index, Shared* shared) : index_(index), shared_(shared) {}

  void start(const client::Client& client, const std::string& scene_id, v1::PvsEncoding encoding) {
    client.prepare(&context_, std::chrono::milliseconds(0));
    request_.set_scene_id(scene_id);
    request_.set_encoding(encoding);
    client.stub().async()->View(&context_, this);
    AddHold();  // Released once the pacing thread is done writing.
    StartRead(&response_);
    shared_->open.fetch_add(1, std::memory_order_relaxed);
    StartCall();
  }

  /// From the pacing thread: sends one frame unless a write is outstanding.
  /// Returns false when the tick was skipped for that reason.
  bool send(std::uint64_t frame, double t, const Camera& camera) {
    {
      std::lock_guard<std::mutex> lock(mu_);
      if (hold_released_ || closing_ || read_ended_ || write_failed_) return true;  // Stream over.
      if (writing_) return false;
      writing_ = true;
      if (!first_) {
        request_.clear_scene_id();
        request_.clear_encoding();
      }
      if (first_) first_sent_ = Clock::now();
      first_ = false;
      request_.set_frame(frame);
      request_.set_t(t);
      client::to_proto(camera, request_.mutable_camera());
      if (pending_.size() >= kMaxPending) pending_.pop_front();  // Never answered: forget.
      pending_.emplace_back(frame, Clock::now());
    }
    // Outside the lock: a reaction may run on another thread at any time and
    // takes the lock itself; `request_` is untouched until OnWriteDone.
    StartWrite(&request_);
    return true;
  }

  /// From the pacing thread: no more frames; WritesDone once no write is outstanding.
  void close() {
    std::unique_lock<std::mutex> lock(mu_);
    closing_ = true;
    release_if_idle(lock);
  }

  /// Cancels the stream (the end's deadline passed); OnDone follows.
  void cancel() {
    cancelled_by_us_.store(true);
    context_.TryCancel();
  }
  bool is_done() const { return done_.load(); }

  void OnWriteDone(bool ok) override {
    std::unique_lock<std::mutex> lock(mu_);
    writing_ = false;
    if (!ok) write_failed_ = true;  // The stream is broken; OnDone says why.
    release_if_idle(lock);
  }

  void OnReadDone(bool ok) override {
    if (!ok) {
      std::unique_lock<std::mutex> lock(mu_);
      read_ended_ = true;
      release_if_idle(lock);
      return;
    }
    const Clock::time_point now = Clock::now();
    const std::uint64_t frame = response_.frame();
    Clock::time_point sent{};
    bool found = false;
    {
      std::lock_guard<std::mutex> lock(mu_);
      // Answers come in frame order; earlier pending frames were replaced on
      // the server (latest frame wins) and will never be answered.
      while (!pending_.empty() && pending_.front().first < frame) pending_.pop_front();
      if (!pending_.empty() && pending_.front().first == frame) {
        sent = pending_.front().second;
        pending_.pop_front();
        found = true;
      }
      // The first gap runs from the first send: a stream the server makes
      // wait for its first answer shows there.
      const bool first_answer = last_answer_ == Clock::time_point{};
      const Clock::time_point since = first_answer ? first_sent_ : last_answer_;
      shared_->gap.add(std::chrono::duration<double, std::micro>(now - since).count());
      if (first_answer) shared_->first_answer.add(std::chrono::duration<double, std::micro>(now - first_sent_).count());
      last_answer_ = now;
    }
    if (found) shared_->latency.add(std::chrono::duration<double, std::micro>(now - sent).count());
    shared_->frames.fetch_add(1, std::memory_order_relaxed);
    const std::int64_t at =
        std::chrono::duration_cast<std::chrono::nanoseconds>(now - shared_->start).count();
    std::int64_t prev = shared_->last_answer_ns.load(std::memory_order_relaxed);
    while (at > prev && !shared_->last_answer_ns.compare_exchange_weak(prev, at, std::memory_order_relaxed)) {
    }
    shared_->server_skipped.fetch_add(response_.frames_skipped(), std::memory_order_relaxed);
    StartRead(&response_);
  }

  void OnDone(const grpc::Status& status) override {
    shared_->open.fetch_sub(1, std::memory_order_relaxed);
    std::lock_guard<std::mutex> lock(shared_->mu);
    if (!status.ok()) {
      if (status.error_code() == grpc::StatusCode::CANCELLED && cancelled_by_us_.load()) {
        ++shared_->cancelled_at_end;
      } else {
        ++shared_->errors[client::status_code_name(status.error_code())];
        if (shared_->first_error.empty()) {
          shared_->first_error = "viewer " + std::to_string(index_) + ": " +
                                 client::describe(status, shared_->address);
        }
      }
    }
    done_.store(true);
    ++shared_->done;
    // Notified under the lock: the waiting thread may free `shared_` as soon
    // as it sees the last stream done.
    shared_->cv.notify_all();
  }


 private:
  static constexpr std::size_t kMaxPending = 4096;

  /// With `lock` held: once no more writes will come and none is
  /// outstanding, sends WritesDone (if the stream still works) and releases
  /// the hold, exactly once.
  void release_if_idle(std::unique_lock<std::mutex>& lock) {
    if (hold_released_ || writing_ || !(closing_ || read_ended_ || write_failed_)) return;
    hold_released_ = true;
    const bool writes_done = closing_ && !read_ended_ && !write_failed_;
    lock.unlock();
    if (writes_done) StartWritesDone();
    RemoveHold();
  }

  const int index_;
  Shared* const shared_;
  grpc::ClientContext context_;
  v1::ViewRequest request_;    // Owned by the outstanding write.
  v1::ViewResponse response_;  // Owned by the outstanding read.
  std::atomic<bool> cancelled_by_us_{false};
  std::atomic<bool> done_{false};

  std::mutex mu_;
  bool first_ = true;          // Guarded by mu_.
  bool writing_ = false;       // Guarded by mu_.
  bool closing_ = false;       // Guarded by mu_.
  bool read_ended_ = false;    // Guarded by mu_.
  bool write_failed_ = false;  // Guarded by mu_.
  bool hold_released_ = false; // Guarded by mu_.
  std::deque<std::pair<std::uint64_t, Clock::time_point>> pending_;  // Guarded by mu_.
  Clock::time_point first_sent_{};   // Guarded by mu_.
  Clock::time_point last_answer_{};  // Guarded by mu_: none yet when zero.
};

/// Cameras of the viewers: looped from a frames file, or an orbit.
class CameraSource {
 public:
  CameraSource(std::vector<Camera> cameras, int viewers)
      : cameras_(std::move(cameras)), viewers_(viewers) {}
  CameraSource(const Vec3& bounds_min, const Vec3& bounds_max, int viewers)
      : viewers_(viewers) {
    center_ = 0.5 * (bounds_min + bounds_max);
    const Vec3 extent = bounds_max - bounds_min;
    radius_x_ = 0.35 * extent.x;
    radius_z_ = 0.35 * extent.z;
    far_ = 2.0 * std::sqrt(extent.x * extent.x + extent.y * extent.y + extent.z * extent.z);
  }

  /// Camera of viewer `v` at its tick `tick`, wall time `t` (seconds).
  Camera at(int v, std::uint64_t tick, double t) const {
    if (!cameras_.empty()) {
      const std::size_t n = cameras_.size();
      const std::size_t offset = static_cast<std::size_t>(v) * n / static_cast<std::size_t>(viewers_);
      return cameras_[(offset + tick) % n];
    }
    // Eye on an ellipse at mid height, one lap in kLapSeconds, looking at the
    // centre's height-level point; viewers evenly phase-shifted.
    const double phase = 2.0 * std::numbers::pi * static_cast<double>(v) / viewers_;
    const double a = phase + 2.0 * std::numbers::pi * t / kLapSeconds;
    Camera c;
    c.eye = center_ + Vec3(radius_x_ * std::cos(a), 0.0, radius_z_ * std::sin(a));
    c.dir = Vec3(-radius_x_ * std::cos(a), 0.0, -radius_z_ * std::sin(a));
    if (c.dir.x == 0.0 && c.dir.z == 0.0) c.dir = Vec3(1.0, 0.0, 0.0);  // Degenerate bounds.
    c.up = Vec3(0.0, 1.0, 0.0);
    c.fov_y_deg = 60.0;
    c.aspect = 16.0 / 9.0;
    c.near = 0.05;
    c.far = far_;
    return c;
  }

 private:
  static constexpr double kLapSeconds = 20.0;
  std::vector<Camera> cameras_;
  int viewers_;
  Vec3 center_{0.0};
  double radius_x_ = 0.0;
  double radius_z_ = 0.0;
  double far_ = 1.0;
};

bool read_cameras(const std::string& path, std::vector<Camera>* cameras) {
  std::vector<FrameInput> frames;
  if (!read_frames(path, "loadgen", &frames)) return false;
  for (const FrameInput& f : frames) cameras->push_back(f.camera);
  return true;
}

}  // namespace

int run_loadgen(const LoadgenArgs& args) {
  // Arguments.
  std::string message;
  if (!valid_scene_id(args.scene, &message)) return report(FormatError{"", 0, "--scene", message});
  if (args.viewers < 1 || args.viewers > 100'000) {
    return report(FormatError{"", 0, "--viewers", "must be in [1, 100000], got " + std::to_string(args.viewers)});
  }
  if (!std::isfinite(args.rate) || args.rate <= 0.0 || args.rate > 10'000.0) {
    return report(FormatError{"", 0, "--rate", "must be in (0, 10000] frames per second per viewer"});
  }
  if (!std::isfinite(args.duration) || args.duration <= 0.0 || args.duration > 7 * 86400.0) {
    return report(FormatError{"", 0, "--duration", "must be in (0, 604800] seconds"});
  }
  if (args.connections < 0 || args.connections > 1024) {
    return report(FormatError{"", 0, "--connections", "must be in [0, 1024] (0: one per 100 viewers), got " +
                                                         std::to_string(args.connections)});
  }
  std::vector<Camera> cameras;
  if (!args.frames.empty() && !read_cameras(args.frames, &cameras)) return kExitError;
  // Open the report file now, so that a bad path fails before the run.
  OutputFile json_out;
  if (!args.json.empty() && !json_out.open(args.json, &message)) {
    return report(FormatError{args.json, 0, "", message});
  }

  // The scene: exists, reachable, and its bounds for the orbit.
  int code = kExitOk;
  const std::unique_ptr<client::Client> control = open_client(args.net, &code);
  if (control == nullptr) return code;
  v1::SceneInfo info;
  if (const grpc::Status st = control->get_scene_stats(args.scene, &info); !st.ok()) {
    return report_status(st, args.net.server, "");
  }
  const CameraSource source =
      cameras.empty()
          ? CameraSource(client::from_proto(info.bounds_min()), client::from_proto(info.bounds_max()),
                         args.viewers)
          : CameraSource(std::move(cameras), args.viewers);

  // Connections: gRPC multiplexes streams on one TCP connection per channel;
  // a few connections spread the load over the server's I/O threads.
  const int connections =
      args.connections > 0 ? std::min(args.connections, args.viewers) : (args.viewers + 99) / 100;
  std::vector<std::unique_ptr<client::Client>> clients;
  for (int c = 0; c < connections; ++c) {
    std::unique_ptr<client::Client> cl = open_client(args.net, &code, c + 1);
    if (cl == nullptr) return code;
    clients.push_back(std::move(cl));
  }

  // Shared state and reactors live on the heap: if some stream never ends
  // (it should not, cancelled), they are leaked rather than freed under it.
  auto shared = std::make_unique<Shared>();
  shared->address = args.net.server;
  const Clock::time_point start = Clock::now();
  shared->start = start;
  std::vector<std::unique_ptr<Viewer>> viewers;
  viewers.reserve(static_cast<std::size_t>(args.viewers));
  const v1::PvsEncoding encoding = args.delta ? v1::PVS_DELTA : v1::PVS_FULL;
  for (int v = 0; v < args.viewers; ++v) {
    viewers.push_back(std::make_unique<Viewer>(v, shared.get()));
    viewers.back()->start(*clients[static_cast<std::size_t>(v % connections)], args.scene, encoding);
  }

  // Pacing: viewer v's tick k is due at start + (k + v / N) / rate. A tick
  // due more than one period ago is dropped (counted as a skipped send), so
  // a late pacing thread catches up instead of bursting.
  const bool tty = ::isatty(STDERR_FILENO) != 0;
  const auto seconds = [](double s) {
    return std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(s));
  };
  const Clock::time_point end = start + seconds(args.duration);
  const Clock::duration period = seconds(1.0 / args.rate);
  Clock::time_point next_progress = start + std::chrono::seconds(1);
  bool progress_shown = false;
  const auto show_progress = [&](Clock::time_point now) {
    const double elapsed = std::chrono::duration<double>(now - start).count();
    std::fprintf(stderr, "%sloadgen: %.1f/%g s, %d viewers, %s frames, p99 %.1f ms%s",
                 tty ? "\r" : "", elapsed, args.duration, shared->open.load(),
                 with_commas(shared->frames.load()).c_str(),
                 shared->latency.percentile_us(99.0) / 1000.0, tty ? "\x1b[K" : "\n");
    std::fflush(stderr);
    progress_shown = true;
  };

  std::uint64_t tick = 0;
  int cursor = 0;
  const double n_viewers = static_cast<double>(args.viewers);
  for (;;) {
    const Clock::time_point due =
        start + seconds((static_cast<double>(tick) + cursor / n_viewers) / args.rate);
    if (due >= end) break;
    Clock::time_point now = Clock::now();
    if (!args.quiet && now >= next_progress) {
      show_progress(now);
      while (next_progress <= now) next_progress += std::chrono::seconds(1);
    }
    if (due > now) {
      std::this_thread::sleep_until(args.quiet ? due : std::min(due, next_progress));
      continue;
    }
    Viewer& viewer = *viewers[static_cast<std::size_t>(cursor)];
    if (now - due > period) {
      shared->send_skipped.fetch_add(1, std::memory_order_relaxed);
    } else {
      // Never decreasing along a stream: the clock is monotonic.
      const double t = std::chrono::duration<double>(now - start).count();
      if (!viewer.send(tick, t, source.at(cursor, tick, t))) {
        shared->send_skipped.fetch_add(1, std::memory_order_relaxed);
      }
    }
    if (++cursor == args.viewers) {
      cursor = 0;
      ++tick;
    }
  }

  // The end: WritesDone everywhere, a bounded wait, then cancel the rest.
  for (auto& v : viewers) v->close();
  const auto wait_all = [&](std::chrono::seconds limit) {
    std::unique_lock<std::mutex> lock(shared->mu);
    return shared->cv.wait_for(lock, limit, [&] { return shared->done == args.viewers; });
  };
  bool all_done = wait_all(std::chrono::seconds(10));
  if (!all_done) {
    for (auto& v : viewers) {
      if (!v->is_done()) v->cancel();
    }
    all_done = wait_all(std::chrono::seconds(5));
  }
  if (!args.quiet && progress_shown) {
    if (tty) std::fputs("\r\x1b[K", stderr);
    std::fflush(stderr);
  }
  if (!all_done) {
    // Reactors must outlive OnDone; never free them under a live stream.
    for (auto& v : viewers) (void)v.release();
    (void)shared.release();
    std::fprintf(stderr, "voxvis: internal error: some View streams did not end after cancellation\n");
    return kExitInternal;
  }

  // The report.
  const std::uint64_t frames = shared->frames.load();
  // Over the time answers took to come, not the sending time: a saturated
  // server still answers queued frames after the end, and those must not
  // count as if they had come within the duration.
  const double answer_seconds = static_cast<double>(shared->last_answer_ns.load()) * 1e-9;
  const double fps = answer_seconds > 0.0 ? static_cast<double>(frames) / answer_seconds : 0.0;
  const double p50 = shared->latency.percentile_us(50.0) / 1000.0;
  const double p99 = shared->latency.percentile_us(99.0) / 1000.0;
  const double max_ms = shared->latency.max_us() / 1000.0;
  const std::uint64_t answered_streams = shared->first_answer.count();
  const double first_p50 = shared->first_answer.percentile_us(50.0) / 1000.0;
  const double first_max = shared->first_answer.max_us() / 1000.0;
  const double gap_p99 = shared->gap.percentile_us(99.0) / 1000.0;
  const double gap_max = shared->gap.max_us() / 1000.0;
  std::string errors_text;
  nlohmann::json errors_json = nlohmann::json::object();
  for (const auto& [name, count] : shared->errors) {
    if (!errors_text.empty()) errors_text += ", ";
    errors_text += name + " " + std::to_string(count);
    errors_json[name] = count;
  }
  if (errors_text.empty()) errors_text = "none";
  if (shared->cancelled_at_end > 0) {
    errors_text += " (" + std::to_string(shared->cancelled_at_end) + " streams cancelled after the end)";
  }
  std::printf(
      "loadgen: %d viewers at %g Hz for %g s on scene %s (%s, %d connection%s)\n"
      "  frames answered  %s (%.1f per second)\n"
      "  latency ms       p50 %.3f, p99 %.3f, max %.3f\n"
      "  first answer ms  p50 %.3f, max %.3f (%s of %d streams answered)\n"
      "  answer gaps ms   p99 %.3f, max %.3f\n"
      "  server skipped   %s frames\n"
      "  send skipped     %s ticks\n"
      "  errors           %s\n",
      args.viewers, args.rate, args.duration, args.scene.c_str(),
      args.delta ? "PVS_DELTA" : "PVS_FULL", connections, connections == 1 ? "" : "s",
      with_commas(frames).c_str(), fps, p50, p99, max_ms, first_p50, first_max,
      with_commas(answered_streams).c_str(), args.viewers, gap_p99, gap_max,
      with_commas(shared->server_skipped.load()).c_str(),
      with_commas(shared->send_skipped.load()).c_str(), errors_text.c_str());
  std::fflush(stdout);

  if (!args.json.empty()) {
    const nlohmann::json report_json = {
        {"viewers", args.viewers},
        {"rate_hz", args.rate},
        {"duration_s", args.duration},
        {"frames", frames},
        {"fps", fps},
        {"p50_ms", p50},
        {"p99_ms", p99},
        {"max_ms", max_ms},
        {"streams_answered", answered_streams},
        {"first_answer_p50_ms", first_p50},
        {"first_answer_max_ms", first_max},
        {"gap_p99_ms", gap_p99},
        {"gap_max_ms", gap_max},
        {"server_skipped", shared->server_skipped.load()},
        {"send_skipped", shared->send_skipped.load()},
        {"errors", errors_json},
    };
    const std::string text = report_json.dump(2) + "\n";
    if (!json_out.write(text) || !json_out.commit(&message)) {
      if (message.empty()) message = std::string("cannot write: ") + std::strerror(errno);
      return report(FormatError{args.json, 0, "", message});
    }
  }

  if (!shared->first_error.empty()) {
    std::fprintf(stderr, "voxvis: error: %s\n", shared->first_error.c_str());
    return kExitError;
  }
  return kExitOk;
}

}  // namespace voxvis::cli
