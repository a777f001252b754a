#include "pool.h"

#include <utility>

namespace voxvis::server {

WorkerPool::WorkerPool(unsigned threads) {
  if (threads == 0) threads = 1;
  workers_.reserve(threads);
  for (unsigned i = 0; i < threads; ++i) workers_.emplace_back([this, i] { run(i); });
}

WorkerPool::~WorkerPool() {
  {
    std::lock_guard<std::mutex> lock(mu_);
    stop_ = true;
  }
  cv_.notify_all();
  for (std::thread& t : workers_) t.join();
}

void WorkerPool::submit(Job job) {
  {
    std::lock_guard<std::mutex> lock(mu_);
    queue_.push_back(std::move(job));
  }
  cv_.notify_one();
}

void WorkerPool::drain() {
  std::unique_lock<std::mutex> lock(mu_);
  idle_cv_.wait(lock, [this] { return queue_.empty() && running_ == 0; });
}

void WorkerPool::run(unsigned /*index*/) {
  Scratch scratch;
  std::unique_lock<std::mutex> lock(mu_);
  for (;;) {
    cv_.wait(lock, [this] { return stop_ || !queue_.empty(); });
    if (queue_.empty()) return;  // stop_ and nothing left to run.
    Job job = std::move(queue_.front());
    queue_.pop_front();
    ++running_;
    lock.unlock();
    job(scratch);
    job = nullptr;  // Release what the job holds before counting it done.
    lock.lock();
    --running_;
    if (queue_.empty() && running_ == 0) idle_cv_.notify_all();
  }
}

void Strand::post(Job job) {
  {
    std::lock_guard<std::mutex> lock(mu_);
    queue_.push_back(std::move(job));
    if (scheduled_) return;
    scheduled_ = true;
  }
  pool_.submit([self = shared_from_this()](Scratch& s) { self->run_some(s); });
}

void Strand::run_some(Scratch& scratch) {
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
    job(scratch);
  }
  std::lock_guard<std::mutex> lock(mu_);
  if (queue_.empty()) {
    scheduled_ = false;
    return;
  }
  pool_.submit([self = shared_from_this()](Scratch& s) { self->run_some(s); });
}

}  // namespace voxvis::server
