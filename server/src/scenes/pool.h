// pool.h — the worker pool that runs frames and moves, and strands that
// serialize a sequence of jobs on it.
//
// Admission is fair between clients: every job is submitted under a client
// key (the server uses the connection's peer address), each key has its own
// FIFO queue, and workers take one job from each key with work in turn
// (round robin). A client that queues a thousand frames therefore delays
// another client's frame by about one job per busy client, not by its whole
// backlog.
//
// Workers never block on each other's work except on a scene's lock. Jobs of
// one Strand run one at a time, in the order posted, on any worker; the
// server uses one per scene for its move batches, keyed by the scene. A
// strand with work occupies one worker at a time and hands it back after a
// few jobs, so one busy scene cannot starve the others. Each worker owns one
// Scratch (per-frame working memory), reused across scenes.
//
// A job that throws does not end the process nor stop its strand: the pool
// catches the exception, hands its text to the error handler and goes on.
// That is the last line; the server's jobs catch their own engine calls
// first, so that the call they serve is answered (INTERNAL).
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <unordered_map>
#include <vector>

#include "voxvis/scene.h"

namespace voxvis::server {

/// Lowers the calling thread's scheduling priority to nice 10, so that it
/// takes only the CPU that threads at the normal priority leave. Linux keeps
/// a nice value per thread, and threads created afterwards by this one (an
/// OpenGL driver's, say) inherit it. Best effort: without it the work is only
/// less polite.
void lower_this_thread_priority();

/// A job. Lambdas of at most two pointers' worth of trivially copyable
/// captures (`[this, i]`) fit std::function's own storage: submitting one
/// allocates nothing.
using Job = std::function<void(Scratch&)>;

/// A FIFO queue in one growing ring buffer: unlike std::deque, which frees
/// and allocates a block every few elements as it is cycled through, it
/// allocates only when it holds more than it ever has.
template <class T>
class RingQueue {
 public:
  bool empty() const { return size_ == 0; }
  std::size_t size() const { return size_; }
  T& front() { return slots_[head_]; }
  void push_back(T value) {
    if (size_ == slots_.size()) grow();
    slots_[(head_ + size_) % slots_.size()] = std::move(value);
    ++size_;
  }
  void pop_front() {
    slots_[head_] = T{};  // Releases what the element holds.
    head_ = (head_ + 1) % slots_.size();
    --size_;
  }

 private:
  void grow() {
    std::vector<T> bigger(slots_.empty() ? 8 : 2 * slots_.size());
    for (std::size_t i = 0; i < size_; ++i) bigger[i] = std::move(slots_[(head_ + i) % slots_.size()]);
    slots_.swap(bigger);
    head_ = 0;
  }
  std::vector<T> slots_;
  std::size_t head_ = 0;
  std::size_t size_ = 0;
};
/// Told the text of an exception a job let escape.
using JobErrorHandler = std::function<void(const std::string&)>;

class WorkerPool {
 public:
  /// Starts `threads` workers (at least 1). `on_error` (may be empty) is
  /// called, on the worker, for every exception a job lets escape. With
  /// `background`, the workers run at a lower scheduling priority (nice 10),
  /// so that they take what CPU the other threads leave: for long work that
  /// must not delay answers.
  explicit WorkerPool(unsigned threads, JobErrorHandler on_error = {}, bool background = false);
  /// Runs every job already submitted, then joins the workers.
  ~WorkerPool();
  WorkerPool(const WorkerPool&) = delete;
  WorkerPool& operator=(const WorkerPool&) = delete;

  /// Queues `job` behind the earlier jobs of the same `client`; clients take
  /// turns (see above).
  void submit(const std::string& client, Job job);
  /// Blocks until no job is queued or running (jobs may submit more jobs).
  void drain();
  unsigned threads() const { return static_cast<unsigned>(workers_.size()); }
  /// Jobs queued and not yet started, all clients together.
  std::size_t queued() const;
  /// Exceptions jobs let escape so far.
  std::uint64_t failed() const { return failed_.load(std::memory_order_relaxed); }
  /// Runs `job`, catching what it throws (counted, handed to the handler).
  void run_guarded(Job& job, Scratch& scratch);

 private:
  void run(bool background);

  /// One client's jobs. Kept when empty, so that a client whose queue
  /// empties and fills again each frame allocates nothing; the empty ones are
  /// dropped when there are more than kKeptQueues.
  struct ClientQueue {
    RingQueue<Job> jobs;
    bool in_turns = false;
  };
  static constexpr std::size_t kKeptQueues = 256;

  mutable std::mutex mu_;
  std::condition_variable cv_;       // Guarded by mu_: new job or stop.
  std::condition_variable idle_cv_;  // Guarded by mu_: queues empty and no job running.
  std::unordered_map<std::string, ClientQueue> queues_;  // Guarded by mu_ (nodes never move).
  RingQueue<ClientQueue*> turns_;    // Guarded by mu_: each queue with jobs once, next first.
  std::size_t queued_ = 0;           // Guarded by mu_.
  unsigned running_ = 0;             // Guarded by mu_.
  bool stop_ = false;                // Guarded by mu_.
  JobErrorHandler on_error_;
  std::atomic<std::uint64_t> failed_{0};
  std::vector<std::thread> workers_;
};

/// Serializes jobs on a pool. Must outlive its queued jobs: hold it in a
/// shared_ptr and keep it alive from the jobs (Strand::post does).
class Strand : public std::enable_shared_from_this<Strand> {
 public:
  /// `client`: the key the strand's turns are submitted under.
  Strand(WorkerPool& pool, std::string client) : pool_(pool), client_(std::move(client)) {}
  void post(Job job);
  /// Whether the calling thread is running one of this strand's jobs now:
  /// what only the strand may touch asserts it (VOXVIS_ASSERT).
  bool runs_here() const;

 private:
  void run_some(Scratch& scratch);

  /// Jobs a strand runs before handing its worker back (fairness between scenes).
  static constexpr int kBatch = 4;

  WorkerPool& pool_;
  const std::string client_;
  std::mutex mu_;
  RingQueue<Job> queue_;  // Guarded by mu_.
  bool scheduled_ = false; // Guarded by mu_: a run_some is submitted or running.
};

}  // namespace voxvis::server
