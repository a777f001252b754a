// verifier.cpp — see verifier.h.
#include "scenes/verifier.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <exception>
#include <future>
#include <iterator>
#include <utility>

#include "scenes/pool.h"
#include "voxvis/format.h"
#include "voxvis/raycast.h"

namespace voxvis::server {

std::vector<ObjectDesc> objects_at(const std::vector<ObjectDesc>& objects, const std::vector<Move>& centers) {
  std::vector<ObjectDesc> out = objects;
  auto it = out.begin();
  for (const Move& m : centers) {
    it = std::lower_bound(it, out.end(), m.id, [](const ObjectDesc& o, ObjectId id) { return o.id < id; });
    if (it == out.end()) break;
    if (it->id != m.id) continue;
    it->center = m.center;
    if (m.has_rotation && it->shape == Shape::Mesh) it->rotation = m.rotation;
  }
  return out;
}

std::unique_ptr<Verifier> Verifier::start(const VerifyConfig& config, Log log, std::string* error) {
  std::unique_ptr<Verifier> v(new Verifier(config, std::move(log)));
  // The renderer is made on the verifier's thread, which keeps its context
  // current; start() waits for the outcome so that a machine without EGL is
  // a start error.
  std::promise<std::string> ready;
  std::future<std::string> outcome = ready.get_future();
  v->thread_ = std::thread([raw = v.get(), ready = std::move(ready)]() mutable {
    // Before the context exists: llvmpipe's rendering threads, made with it,
    // inherit the lower priority, and checking never takes CPU from answers.
    lower_this_thread_priority();
    std::string err;
    std::unique_ptr<render::Renderer> r = render::Renderer::create(raw->config_.context, &err);
    if (!r) err = "EGL: " + err;
    if (r && (raw->config_.width > r->info().max_size || raw->config_.height > r->info().max_size))
      err = "--verify-resolution " + std::to_string(raw->config_.width) + "x" + std::to_string(raw->config_.height) +
            " exceeds this OpenGL's limit of " + std::to_string(r->info().max_size) + " pixels a side";
    if (!err.empty()) {
      ready.set_value(err);
      return;
    }
    raw->info_ = r->info();
    ready.set_value("");
    std::unique_lock<std::mutex> lock(raw->mu_);
    for (;;) {
      raw->cv_.wait(lock, [raw] { return raw->stop_ || !raw->queue_.empty(); });
      if (raw->queue_.empty()) break;  // Stopping, nothing left.
      VerifyJob job = std::move(raw->queue_.front());
      raw->queue_.pop_front();
      raw->busy_ = true;
      lock.unlock();
      // A check that throws (memory exhausted, a driver error) drops that
      // frame, counted and logged; it never ends the process.
      try {
        raw->verify(job, *r);
      } catch (const std::exception& e) {
        raw->log_(std::string("verify: scene '") + job.scene + "' frame " + std::to_string(job.frame) +
                  " not verified: " + e.what());
        raw->dropped(job.metrics.get());
      }
      lock.lock();
      raw->busy_ = false;
      raw->cv_.notify_all();
    }
  });
  *error = outcome.get();
  if (!error->empty()) {
    v->thread_.join();
    *error = "verify mode: " + *error;
    return nullptr;
  }
  return v;
}

Verifier::~Verifier() {
  {
    std::lock_guard<std::mutex> lock(mu_);
    stop_ = true;
    queue_.clear();
  }
  cv_.notify_all();
  if (thread_.joinable()) thread_.join();
}

bool Verifier::sample() {
  if (!(config_.fraction > 0.0)) return false;
  std::lock_guard<std::mutex> lock(mu_);
  const std::uint64_t n = calls_++;
  // Frame n is taken when floor((n+1) f) > floor(n f): exactly f of them.
  return std::floor(static_cast<double>(n + 1) * config_.fraction) >
         std::floor(static_cast<double>(n) * config_.fraction);
}

void Verifier::submit(VerifyJob job) {
  std::unique_lock<std::mutex> lock(mu_);
  if (stop_ || queue_.size() >= config_.queue) {
    ++totals_.dropped;
    lock.unlock();
    if (job.metrics) job.metrics->verify_dropped();
    return;
  }
  queue_.push_back(std::move(job));
  lock.unlock();
  cv_.notify_all();
}

void Verifier::dropped(SceneMetrics* metrics) {
  {
    std::lock_guard<std::mutex> lock(mu_);
    ++totals_.dropped;
  }
  if (metrics) metrics->verify_dropped();
}

void Verifier::drain() {
  std::unique_lock<std::mutex> lock(mu_);
  cv_.wait(lock, [this] { return stop_ || (queue_.empty() && !busy_); });
}

Verifier::Totals Verifier::totals() const {
  std::lock_guard<std::mutex> lock(mu_);
  return totals_;
}

void Verifier::verify(VerifyJob& job, render::Renderer& r) {
  std::vector<ObjectId> visible;
  render::VisibleStats st;
  std::string error;
  const render::VisibleOptions options{config_.width, config_.height, render::Method::Ids};
  if (!r.visible(job.objects, job.camera, options, nullptr, &visible, &st, &error)) {
    log_("verify: scene '" + job.scene + "' frame " + std::to_string(job.frame) + " not verified: " + error);
    std::lock_guard<std::mutex> lock(mu_);
    ++totals_.dropped;
    if (job.metrics) job.metrics->verify_dropped();
    return;
  }
  std::vector<ObjectId> sighted, missed, edge_only;
  std::set_difference(visible.begin(), visible.end(), job.pvs.begin(), job.pvs.end(), std::back_inserter(sighted));
  // Confirmed in double precision near a pixel showing it, or seen only
  // along an edge (not visible: docs/verify.md, "What a miss is").
  if (!sighted.empty())
    raycast::confirm_near_pixels(job.objects, job.camera, config_.width, config_.height, r.last_ids(), sighted,
                                 &missed, &edge_only);
  if (job.metrics) {
    job.metrics->verified(missed.size());
    if (!edge_only.empty()) job.metrics->verify_edge_only(edge_only.size());
  }
  {
    std::lock_guard<std::mutex> lock(mu_);
    ++totals_.verified;
    totals_.objects_missed += missed.size();
    totals_.edge_only += edge_only.size();
    totals_.frames_missed += missed.empty() ? 0 : 1;
  }
  if (missed.empty()) return;
  // One line an operator can act on: who, which frame, what was missed, and
  // the frame as a frames-file line to replay (the scene's positions at that
  // frame are not in it: see docs/server.md).
  std::string ids;
  for (ObjectId id : missed) {
    if (!ids.empty()) ids += ',';
    ids += std::to_string(id);
  }
  FrameInput f;
  f.t = job.t;
  f.camera = job.camera;
  log_("verify: MISS scene '" + job.scene + "' viewer " + job.viewer + " frame " + std::to_string(job.frame) +
       ": " + std::to_string(missed.size()) + " visible object(s) not in the PVS of " +
       std::to_string(job.pvs.size()) + " at " + std::to_string(config_.width) + "x" +
       std::to_string(config_.height) + ": [" + ids + "]; frame " + frame_to_json(f));
}

}  // namespace voxvis::server
