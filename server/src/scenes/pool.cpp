#include "scenes/pool.h"

#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <exception>
#include <utility>

namespace voxvis::server {

void lower_this_thread_priority() {
  (void)setpriority(PRIO_PROCESS, static_cast<id_t>(syscall(SYS_gettid)), 10);
}

WorkerPool::WorkerPool(unsigned threads, JobErrorHandler on_error, bool background)
    : on_error_(std::move(on_error)) {
  if (threads == 0) threads = 1;
  workers_.reserve(threads);
  for (unsigned i = 0; i < threads; ++i) workers_.emplace_back([this, background] { run(background); });
}

void WorkerPool::run_guarded(Job& job, Scratch& scratch) {
  std::string what;
  try {
    job(scratch);
    return;
  } catch (const std::exception& e) {
    what = e.what();
  } catch (...) {
    what = "an exception that is not a std::exception";
  }
  failed_.fetch_add(1, std::memory_order_relaxed);
  if (on_error_) on_error_(what);
}

WorkerPool::~WorkerPool() {
  {
    std::lock_guard<std::mutex> lock(mu_);
    stop_ = true;
  }
  cv_.notify_all();
  for (std::thread& t : workers_) t.join();
}

void WorkerPool::submit(const std::string& client, Job job) {
  {
    std::lock_guard<std::mutex> lock(mu_);
    auto it = queues_.find(client);
    if (it == queues_.end()) {
      if (queues_.size() >= kKeptQueues) {
        std::erase_if(queues_, [](const auto& kv) { return !kv.second.in_turns; });
      }
      it = queues_.emplace(client, ClientQueue{}).first;
    }
    ClientQueue& q = it->second;
    q.jobs.push_back(std::move(job));
    if (!q.in_turns) {
      q.in_turns = true;
      turns_.push_back(&q);
    }
    ++queued_;
  }
  cv_.notify_one();
}

std::size_t WorkerPool::queued() const {
  std::lock_guard<std::mutex> lock(mu_);
  return queued_;
}

void WorkerPool::drain() {
  std::unique_lock<std::mutex> lock(mu_);
  idle_cv_.wait(lock, [this] { return queued_ == 0 && running_ == 0; });
}

void WorkerPool::run(bool background) {
  if (background) lower_this_thread_priority();
  Scratch scratch;
  std::unique_lock<std::mutex> lock(mu_);
  for (;;) {
    cv_.wait(lock, [this] { return stop_ || queued_ != 0; });
    if (queued_ == 0) return;  // stop_ and nothing left to run.
    // The client whose turn it is gives one job and goes to the back of the
    // line if it has more.
    ClientQueue* q = turns_.front();
    turns_.pop_front();
    Job job = std::move(q->jobs.front());
    q->jobs.pop_front();
    if (q->jobs.empty()) {
      q->in_turns = false;
    } else {
      turns_.push_back(q);
    }
    --queued_;
    ++running_;
    lock.unlock();
    run_guarded(job, scratch);
    job = nullptr;  // Release what the job holds before counting it done.
    lock.lock();
    --running_;
    if (queued_ == 0 && running_ == 0) idle_cv_.notify_all();
  }
}

void Strand::post(Job job) {
  {
    std::lock_guard<std::mutex> lock(mu_);
    queue_.push_back(std::move(job));
    if (scheduled_) return;
    scheduled_ = true;
  }
  pool_.submit(client_, [self = shared_from_this()](Scratch& s) { self->run_some(s); });
}

namespace {

/// The strand whose jobs this thread is running, if any (Strand::runs_here).
thread_local const Strand* running_strand = nullptr;

/// Marks this thread as running `strand`'s jobs for its lifetime.
class RunningStrand {
 public:
  explicit RunningStrand(const Strand* strand) : previous_(running_strand) { running_strand = strand; }
  ~RunningStrand() { running_strand = previous_; }
  RunningStrand(const RunningStrand&) = delete;
  RunningStrand& operator=(const RunningStrand&) = delete;

 private:
  const Strand* previous_;
};

}  // namespace

bool Strand::runs_here() const { return running_strand == this; }

void Strand::run_some(Scratch& scratch) {
  const RunningStrand running(this);
  for (int i = 0; i < kBatch; ++i) {
    Job job;
    {
      std::lock_guard<std::mutex> lock(mu_);
      if (queue_.empty()) {
        scheduled_ = false;
        return;
      }
      job = std::move(queue_.front());
      queue_.pop_front();
    }
    // A job that throws must not leave the strand scheduled with no worker.
    pool_.run_guarded(job, scratch);
  }
  std::lock_guard<std::mutex> lock(mu_);
  if (queue_.empty()) {
    scheduled_ = false;
    return;
  }
  pool_.submit(client_, [self = shared_from_this()](Scratch& s) { self->run_some(s); });
}

}  // namespace voxvis::server
