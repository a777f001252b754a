// loadgen.h — `voxvis loadgen`'s parts shared by its two drivers: one View
// stream per viewer (loadgen_views.cpp), or one Tick stream carrying every
// viewer of a tick (loadgen_ticks.cpp, --tick). loadgen_cmd.cpp checks the
// arguments, runs a driver and reports.
//
// Design choices:
//  * gRPC's callback API: one ClientBidiReactor per stream, no thread per
//    stream. Reads run inside the reactions (each answer starts the next
//    read); writes come from the single pacing thread, which holds each
//    stream open with a hold (AddHold) until it has sent its last write and
//    WritesDone.
//  * At most one write outstanding per stream. A send that finds the
//    previous write still outstanding is skipped and counted ("send
//    skipped"): the client, not the server, is then the bottleneck, and
//    queueing more writes would only measure the client's buffers.
//  * Latencies go into a log histogram (1% buckets) instead of a list, so a
//    long run takes constant memory; percentiles are exact to within 1%.
#pragma once

#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <numbers>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <grpcpp/grpcpp.h>

#include "cli.h"
#include "voxvis/client.h"
#include "voxvis/format.h"

namespace voxvis::cli::loadgen {

using Clock = std::chrono::steady_clock;

/// The server's limit of viewers in one tick (voxvis.proto, TickRequest.viewers).
constexpr int kMaxTickViewers = 1024;

inline Clock::duration seconds(double s) {
  return std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(s));
}

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

/// State shared by all streams and the pacing thread.
struct Shared {
  Histogram latency;       ///< Send to answer: of a frame (View), of a whole tick (Tick).
  Histogram first_answer;  ///< From a stream's first send to its first answer.
  Histogram gap;           ///< Between two answers of one stream (and before the first).
  std::atomic<std::uint64_t> frames{0};          ///< Answers received: one per viewer answered.
  std::atomic<std::uint64_t> answer_errors{0};   ///< Tick entries answered with an error.
  std::atomic<std::uint64_t> ticks_sent{0};      ///< Tick requests written (Tick only).
  std::atomic<std::uint64_t> ticks_answered{0};  ///< Tick responses (Tick only).
  std::atomic<std::uint64_t> server_skipped{0};  ///< Sum of frames_skipped / ticks_skipped.
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

/// A stream the pacing thread writes to: the write, close and hold
/// discipline above, answer timing, and the end's bookkeeping. Derived
/// streams fill `request_` in send's callback and read `response_`
/// in on_answer.
template <class Req, class Resp>
class PacedStream : public grpc::ClientBidiReactor<Req, Resp> {
 public:
  PacedStream(std::string name, Shared* shared) : shared_(shared), name_(std::move(name)) {}

  /// From the pacing thread: `fill(request, first)` writes message number
  /// `seq` unless a write is outstanding. False when skipped for that reason.
  template <class Fill>
  bool send(std::uint64_t seq, Fill&& fill) {
    {
      std::lock_guard<std::mutex> lock(mu_);
      if (hold_released_ || closing_ || read_ended_ || write_failed_) return true;  // Stream over.
      if (writing_) return false;
      writing_ = true;
      const Clock::time_point now = Clock::now();
      if (first_) first_sent_ = now;
      fill(request_, first_);
      first_ = false;
      if (pending_.size() >= kMaxPending) pending_.pop_front();  // Never answered: forget.
      pending_.emplace_back(seq, now);
    }
    // Outside the lock: a reaction may run on another thread at any time and
    // takes the lock itself; `request_` is untouched until OnWriteDone.
    this->StartWrite(&request_);
    return true;
  }

  /// From the pacing thread: no more sends; WritesDone once no write is outstanding.
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
    answered(on_answer(response_));
    this->StartRead(&response_);
  }

  void OnDone(const grpc::Status& status) override {
    shared_->open.fetch_sub(1, std::memory_order_relaxed);
    std::lock_guard<std::mutex> lock(shared_->mu);
    if (!status.ok()) {
      if (status.error_code() == grpc::StatusCode::CANCELLED && cancelled_by_us_.load()) {
        ++shared_->cancelled_at_end;
      } else {
        ++shared_->errors[client::status_code_name(status.error_code())];
        if (shared_->first_error.empty()) shared_->first_error = name_ + ": " + client::describe(status, shared_->address);
      }
    }
    done_.store(true);
    ++shared_->done;
    // Notified under the lock: the waiting thread may free `shared_` as soon
    // as it sees the last stream done.
    shared_->cv.notify_all();
  }

 protected:
  /// Counts an answer's contents; returns the number of the message it answers.
  virtual std::uint64_t on_answer(const Resp& response) = 0;

  /// Starts the call: `start(context, reactor)` is the stub's async method.
  template <class StartFn>
  void begin(const client::Client& client, StartFn&& start) {
    client.prepare(&context_, std::chrono::milliseconds(0));
    start(&context_, this);
    this->AddHold();  // Released once the pacing thread is done writing.
    this->StartRead(&response_);
    shared_->open.fetch_add(1, std::memory_order_relaxed);
    this->StartCall();
  }

  Shared* const shared_;

 private:
  static constexpr std::size_t kMaxPending = 4096;

  /// Records the answer to message `seq`: latency, gaps, the last answer's time.
  void answered(std::uint64_t seq) {
    const Clock::time_point now = Clock::now();
    Clock::time_point sent{};
    bool found = false;
    {
      std::lock_guard<std::mutex> lock(mu_);
      // Answers come in order; earlier pending messages were replaced on the
      // server (latest wins) and will never be answered.
      while (!pending_.empty() && pending_.front().first < seq) pending_.pop_front();
      if (!pending_.empty() && pending_.front().first == seq) {
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
    const std::int64_t at = std::chrono::duration_cast<std::chrono::nanoseconds>(now - shared_->start).count();
    std::int64_t prev = shared_->last_answer_ns.load(std::memory_order_relaxed);
    while (at > prev && !shared_->last_answer_ns.compare_exchange_weak(prev, at, std::memory_order_relaxed)) {
    }
  }

  /// With `lock` held: once no more writes will come and none is
  /// outstanding, sends WritesDone (if the stream still works) and releases
  /// the hold, exactly once.
  void release_if_idle(std::unique_lock<std::mutex>& lock) {
    if (hold_released_ || writing_ || !(closing_ || read_ended_ || write_failed_)) return;
    hold_released_ = true;
    const bool writes_done = closing_ && !read_ended_ && !write_failed_;
    lock.unlock();
    if (writes_done) this->StartWritesDone();
    this->RemoveHold();
  }

  const std::string name_;  // "viewer 3", "tick stream": for messages.
  grpc::ClientContext context_;
  Req request_;    // Owned by the outstanding write.
  Resp response_;  // Owned by the outstanding read.
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

/// The end of a run: close every stream (WritesDone), wait up to 10 s, cancel
/// the rest and wait 5 s more. False when some stream never ended: its
/// reactor must then outlive this process's use of it (the caller leaks it).
template <class Stream>
bool end_streams(std::vector<std::unique_ptr<Stream>>& streams, Shared& shared) {
  for (auto& s : streams) s->close();
  const int n = static_cast<int>(streams.size());
  const auto wait_all = [&](std::chrono::seconds limit) {
    std::unique_lock<std::mutex> lock(shared.mu);
    return shared.cv.wait_for(lock, limit, [&] { return shared.done == n; });
  };
  if (wait_all(std::chrono::seconds(10))) return true;
  for (auto& s : streams) {
    if (!s->is_done()) s->cancel();
  }
  return wait_all(std::chrono::seconds(5));
}

/// The progress line on stderr, at most once a second (unless quiet).
class ProgressLine {
 public:
  ProgressLine(const LoadgenArgs& args, const Shared& shared);
  /// Shows the line when due; returns when the next one is due.
  Clock::time_point update(Clock::time_point now);
  void finish();

 private:
  const LoadgenArgs& args_;
  const Shared& shared_;
  const bool tty_;
  bool shown_ = false;
  Clock::time_point next_;
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

  /// The region flags' fields, set on every camera `at` gives.
  void set_region(const RegionOverride& region) { region_ = region; }

  /// Camera of viewer `v` at its tick `tick`, wall time `t` (seconds).
  Camera at(int v, std::uint64_t tick, double t) const {
    Camera c = path_at(v, tick, t);
    region_.apply(&c);
    return c;
  }

 private:
  Camera path_at(int v, std::uint64_t tick, double t) const {
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

  static constexpr double kLapSeconds = 20.0;
  RegionOverride region_;
  std::vector<Camera> cameras_;
  int viewers_;
  Vec3 center_{0.0};
  double radius_x_ = 0.0;
  double radius_z_ = 0.0;
  double far_ = 1.0;
};

/// The pacing loop: message k is due at start + k / per_second, until the
/// run's duration. `send(k, t)` sends it at `t` seconds since the start and
/// returns false when the stream still had a write outstanding. A message
/// due more than one period (1 / rate) ago is not sent, so a late pacing
/// thread catches up instead of bursting; both count as skipped sends.
template <class Send>
void pace(const LoadgenArgs& args, Shared& shared, ProgressLine& progress, double per_second, Send&& send) {
  const Clock::time_point start = shared.start;
  const Clock::time_point end = start + seconds(args.duration);
  const Clock::duration period = seconds(1.0 / args.rate);
  for (std::uint64_t k = 0;;) {
    const Clock::time_point due = start + seconds(static_cast<double>(k) / per_second);
    if (due >= end) return;
    const Clock::time_point now = Clock::now();
    const Clock::time_point next_progress = progress.update(now);
    if (due > now) {
      std::this_thread::sleep_until(std::min(due, next_progress));
      continue;
    }
    // Never decreasing along a stream: the clock is monotonic.
    if (now - due > period || !send(k, std::chrono::duration<double>(now - start).count()))
      shared.send_skipped.fetch_add(1, std::memory_order_relaxed);
    ++k;
  }
}

/// Runs the View driver: one stream per viewer, spread over `clients`
/// (connections), viewer v's frame k due at start + (k + v / N) / rate.
/// False when some stream never ended (an internal error; reactors leaked).
bool drive_views(const LoadgenArgs& args, const CameraSource& source,
                 const std::vector<std::unique_ptr<client::Client>>& clients, Shared& shared);

/// Runs the Tick driver: one Tick stream, every viewer in each tick, tick k
/// due at start + k / rate. Same return as drive_views.
bool drive_ticks(const LoadgenArgs& args, const CameraSource& source, const client::Client& client,
                 Shared& shared);

}  // namespace voxvis::cli::loadgen
