#include "service.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <optional>
#include <utility>

#include "convert.h"

namespace voxvis::server {
namespace {

using Clock = std::chrono::steady_clock;

grpc::Status invalid(const Status& s) {
  return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, s.str());
}

std::string mib(std::uint64_t bytes) {
  return std::to_string((bytes + (1u << 20) - 1) >> 20) + " MiB";
}

/// a \ b for ascending a and b.
void difference(const std::vector<ObjectId>& a, const std::vector<ObjectId>& b,
                google::protobuf::RepeatedField<std::uint32_t>* out) {
  std::size_t j = 0;
  for (ObjectId id : a) {
    while (j < b.size() && b[j] < id) ++j;
    if (j == b.size() || b[j] != id) out->Add(id);
  }
}

/// Frames of one scene finish in any order: the statistic keeps the latest.
void store_max(std::atomic<double>& a, double v) {
  double cur = a.load(std::memory_order_relaxed);
  while (cur < v && !a.compare_exchange_weak(cur, v, std::memory_order_relaxed)) {
  }
}

/// A request's scene id, checked before any message could echo it.
grpc::Status check_scene_id(const std::string& id, const char* field = "scene_id") {
  if (valid_scene_id(id)) return grpc::Status::OK;
  return invalid(Status::Error(field, "must be 1-64 characters from [A-Za-z0-9._-], not starting "
                                      "with '.' (got " + std::to_string(id.size()) + " bytes)"));
}

/// NOT_FOUND for a (valid, hence short) scene id.
grpc::Status no_scene(const std::string& id) {
  return grpc::Status(grpc::StatusCode::NOT_FOUND, "scene_id: no scene '" + id + "'");
}

grpc::Status deleted(const SceneEntry& e) {
  return grpc::Status(grpc::StatusCode::NOT_FOUND, "scene '" + e.id + "' was deleted");
}

grpc::Status shutting_down_status() {
  return grpc::Status(grpc::StatusCode::UNAVAILABLE, "server is shutting down");
}

void add_ids(const std::vector<ObjectId>& ids, google::protobuf::RepeatedField<std::uint32_t>* out) {
  out->Reserve(static_cast<int>(ids.size()));
  for (ObjectId id : ids) out->AddAlreadyReserved(id);
}

}  // namespace

// ---------------------------------------------------------------------------
// Wake list

class SimReactor;
void deliver_wake(SimReactor* r, std::shared_ptr<const WakeSnapshot> snap);

void SceneEntry::refresh_wake() {
  std::lock_guard<std::mutex> lock(wake_mu);
  // The epoch is read before the set: a change in between is seen again next
  // time, never lost.
  const std::uint64_t epoch = scene->wake_epoch();
  if (epoch == wake_epoch_seen && wake) return;
  wake_epoch_seen = epoch;
  std::vector<ObjectId> ids = scene->wake_set();
  wake_size.store(static_cast<std::uint32_t>(ids.size()), std::memory_order_relaxed);
  if (metrics) metrics->wake_size(ids.size());
  if (wake && wake->ids == ids) return;
  auto snap = std::make_shared<WakeSnapshot>();
  snap->version = wake ? wake->version + 1 : 1;
  snap->ids = std::move(ids);
  wake = snap;
  for (const auto& sink : sinks) {
    std::lock_guard<std::mutex> sink_lock(sink->mu);
    if (sink->reactor) deliver_wake(sink->reactor, wake);
  }
}

void SceneEntry::after_frame(const FrameResult& result) {
  frames_served.fetch_add(1, std::memory_order_relaxed);
  tbvs_active.store(result.stats.tbvs_active, std::memory_order_relaxed);
  if (metrics) metrics->tbvs_active(result.stats.tbvs_active);
  store_max(time, result.t);
  refresh_wake();
}

double SceneEntry::view_time(double t, double lead) const {
  return std::fmin(t, sim_time.load(std::memory_order_relaxed) + lead);
}

void SceneEntry::subscribe(const std::shared_ptr<WakeSink>& sink) {
  refresh_wake();
  std::lock_guard<std::mutex> lock(wake_mu);
  sinks.push_back(sink);
  std::lock_guard<std::mutex> sink_lock(sink->mu);
  if (sink->reactor) deliver_wake(sink->reactor, wake);  // The whole list first.
}

void SceneEntry::unsubscribe(const std::shared_ptr<WakeSink>& sink) {
  std::lock_guard<std::mutex> lock(wake_mu);
  sinks.erase(std::remove(sinks.begin(), sinks.end(), sink), sinks.end());
}

// ---------------------------------------------------------------------------
// What both streams share: admission (token, registration for shutdown), the
// stop-then-finish protocol, and a lifetime that outlasts gRPC's OnDone until
// the last pool job referencing the stream has ended. `Self` provides
// advance_locked() (writes, reads, Finish), on_stop_locked() and on_done()
// (hooks), and on_release() (called once, just before deletion).

template <class Req, class Resp, class Self>
class StreamReactor : public grpc::ServerBidiReactor<Req, Resp>, public Stream {
 public:
  void stop_if(const SceneEntry* scene, const grpc::Status& status) override {
    std::lock_guard<std::mutex> lock(mu_);
    if (scene && entry_.get() != scene) return;
    stop_locked(status);
    self().advance_locked();
  }

  void OnWriteDone(bool ok) override {
    std::lock_guard<std::mutex> lock(mu_);
    writing_ = false;
    if (!ok) stop_locked(grpc::Status(grpc::StatusCode::CANCELLED, "client gone"));
    self().advance_locked();
  }

  void OnCancel() override {
    std::lock_guard<std::mutex> lock(mu_);
    stop_locked(grpc::Status(grpc::StatusCode::CANCELLED, "cancelled"));
    self().advance_locked();
  }

  void OnDone() override {
    if (registered_) svc_->remove_stream(this);
    self().on_done();
    bool del;
    {
      std::lock_guard<std::mutex> lock(mu_);
      done_ = true;
      del = jobs_ == 0;
    }
    if (del) release();
  }

 protected:
  StreamReactor(Service* svc, const char* method) : svc_(svc), method_(method) {}

  /// Checks the call's token and registers the stream. Call from the
  /// derived constructor without holding mu_ (the service's stream lock comes
  /// first in the lock order).
  grpc::Status admit(grpc::CallbackServerContext* ctx, Role role) {
    client_ = ctx->peer();
    const grpc::Status auth = svc_->tokens().authorize(ctx, role);
    registered_ = svc_->add_stream(this);
    if (!auth.ok()) return auth;
    if (!registered_) return grpc::Status(grpc::StatusCode::UNAVAILABLE, "server is shutting down");
    return grpc::Status::OK;
  }

  void stop_locked(const grpc::Status& status) {
    if (!stopping_) {
      stopping_ = true;
      stop_status_ = status;
    }
    self().on_stop_locked();
  }

  /// Finish with the stop status, or OK when the client closed.
  void finish_locked() {
    finished_ = true;
    const grpc::Status s = stopping_ ? stop_status_ : grpc::Status::OK;
    if (!s.ok() && s.error_code() != grpc::StatusCode::CANCELLED) svc_->count_error(method_, s);
    this->Finish(s);
  }

  /// Counts the end of a pool job; true when the stream is to be released.
  bool end_job_locked() {
    --jobs_;
    return done_ && jobs_ == 0;
  }

  void release() {
    self().on_release();
    delete &self();
  }

  Service* svc_;
  const char* method_;
  std::string client_;       // The connection's peer: the pool's admission key. Set in admit.
  bool registered_ = false;  // Written before any reaction can run.
  std::mutex mu_;
  std::shared_ptr<SceneEntry> entry_;  // Guarded by mu_; set by the first message.
  bool writing_ = false, stopping_ = false, finished_ = false, done_ = false;  // Guarded by mu_.
  grpc::Status stop_status_;           // Guarded by mu_.
  int jobs_ = 0;                       // Guarded by mu_: pool jobs referencing this.

 private:
  Self& self() { return static_cast<Self&>(*this); }
};

// ---------------------------------------------------------------------------
// View: one viewer's frames.
//
// State machine (all under mu_): a read is always outstanding until the
// client closes or the stream stops; the newest unanswered request waits in
// pending_ (an older one there is skipped); one frame computes at a time, its
// answer waits in ready_ while a write is in flight; a new frame is computed
// only when no answer is waiting, so a viewer that does not read costs one
// request, one answer and one write in flight. Deltas are taken at write time
// against the last PVS written, so skipped frames never break them.

class ViewReactor final
    : public StreamReactor<v1::ViewRequest, v1::ViewResponse, ViewReactor> {
  friend class StreamReactor<v1::ViewRequest, v1::ViewResponse, ViewReactor>;

 public:
  ViewReactor(Service* svc, grpc::CallbackServerContext* ctx) : StreamReactor(svc, "View") {
    const grpc::Status admitted = admit(ctx, Role::Viewer);
    std::lock_guard<std::mutex> lock(mu_);
    if (admitted.ok()) {
      StartRead(&read_);
    } else {
      stop_locked(admitted);
    }
    advance_locked();
  }

  void OnReadDone(bool ok) override {
    std::lock_guard<std::mutex> lock(mu_);
    if (!ok) {
      eof_ = true;
    } else if (!stopping_) {
      grpc::Status s = accept_locked();
      if (s.ok()) {
        StartRead(&read_);
      } else {
        stop_locked(s);
      }
    }
    advance_locked();
  }

 private:
  struct Pending {
    std::uint64_t frame = 0;
    double t = 0.0;
    Camera camera;
    Clock::time_point received;
  };
  struct Ready {
    std::uint64_t frame = 0;
    double t = 0.0;
    FrameResult result;
    Clock::time_point received;
    std::uint32_t skipped = 0;
  };

  grpc::Status accept_locked() {
    const v1::ViewRequest& r = read_;
    if (!entry_) {
      if (r.scene_id().empty())
        return invalid(Status::Error("scene_id", "the first message of a stream must name the scene"));
      if (grpc::Status s = check_scene_id(r.scene_id()); !s.ok()) return s;
      if (r.encoding() != v1::PVS_FULL && r.encoding() != v1::PVS_DELTA)
        return invalid(Status::Error("encoding", "unknown value " + std::to_string(r.encoding())));
      // entry_ set means counted as a viewer (released in on_release).
      entry_ = svc_->find(r.scene_id());
      if (!entry_) return no_scene(r.scene_id());
      encoding_ = r.encoding();
      entry_->viewers.fetch_add(1, std::memory_order_relaxed);
      if (entry_->metrics) entry_->metrics->viewers(+1);
    } else if (!r.scene_id().empty() && r.scene_id() != entry_->id) {
      return invalid(Status::Error("scene_id", "cannot change within a stream (stream is on '" +
                                                   entry_->id + "')"));
    }
    if (have_frame_ && r.frame() <= last_frame_)
      return invalid(Status::Error("frame", "must increase along a stream: " +
                                                std::to_string(r.frame()) + " after " +
                                                std::to_string(last_frame_)));
    if (Status s = validate_time("t", r.t()); !s) return invalid(s);
    if (have_frame_ && r.t() < last_t_)
      return invalid(Status::Error("t", "must not decrease along a stream"));
    Pending p;
    if (Status s = camera_from_proto(r.camera(), r.has_camera(), &p.camera); !s) return invalid(s);
    have_frame_ = true;
    last_frame_ = r.frame();
    last_t_ = r.t();
    p.frame = r.frame();
    p.t = r.t();
    p.received = Clock::now();
    if (pending_) ++skipped_;
    pending_ = p;
    return grpc::Status::OK;
  }

  void on_stop_locked() { pending_.reset(); }
  void on_done() {}

  void advance_locked() {
    if (finished_) return;
    if (!writing_ && ready_) write_locked();
    if (!stopping_ && !computing_ && pending_ && !ready_) {
      computing_ = true;
      ++jobs_;
      Pending p = *pending_;
      pending_.reset();
      const std::uint32_t skipped = skipped_;
      skipped_ = 0;
      // Frames of one scene run in parallel (the Scene synchronizes itself);
      // this stream's frames one at a time.
      svc_->pool().submit(client_, [this, entry = entry_, p, skipped](Scratch& scratch) {
        compute(*entry, p, skipped, scratch);
      });
    }
    const bool idle = !writing_ && !computing_ && !ready_;
    if (idle && (stopping_ || (eof_ && !pending_))) finish_locked();
  }

  // Pool job.
  void compute(SceneEntry& e, const Pending& p, std::uint32_t skipped, Scratch& scratch) {
    std::optional<Ready> ready;
    grpc::Status error;
    bool stopped;
    {
      std::lock_guard<std::mutex> lock(mu_);
      stopped = stopping_;
    }
    if (stopped) {
      // Cancelled, shut down or deleted while queued: nobody waits for it.
      svc_->count_dropped();
    } else if (e.deleted.load()) {
      error = deleted(e);
    } else {
      Scene& scene = *e.scene;
      if (!viewer_added_) {
        viewer_ = scene.add_viewer();
        viewer_added_ = true;
      }
      ready.emplace();
      ready->frame = p.frame;
      ready->received = p.received;
      ready->skipped = skipped;
      // The scene's clock is shared: a time behind it is taken as it, one
      // too far beyond the simulation's as its limit.
      const double t = e.view_time(p.t, svc_->config().max_view_lead_s);
      Status s = scene.frame(viewer_, p.camera, t, scratch, &ready->result, Scene::Clock::Latest);
      ready->t = ready->result.t;
      if (!s) {
        error = invalid(s);
        ready.reset();
      } else {
        e.after_frame(ready->result);
      }
    }
    bool del;
    {
      std::lock_guard<std::mutex> lock(mu_);
      computing_ = false;
      if (ready) {
        ready_ = std::move(ready);
      } else if (!error.ok()) {
        stop_locked(error);
      }
      advance_locked();
      del = end_job_locked();
    }
    if (del) release();
  }

  void write_locked() {
    Ready& r = *ready_;
    write_.Clear();
    write_.set_frame(r.frame);
    write_.set_t(r.t);
    write_.set_encoding(encoding_);
    std::vector<ObjectId>& pvs = r.result.pvs;
    if (encoding_ == v1::PVS_DELTA) {
      difference(pvs, last_sent_, write_.mutable_added());
      difference(last_sent_, pvs, write_.mutable_removed());
    } else {
      add_ids(pvs, write_.mutable_pvs());
    }
    add_ids(r.result.wake, write_.mutable_wake());
    stats_to_proto(r.result.stats, write_.mutable_stats());
    write_.set_frames_skipped(r.skipped);
    const double latency = std::chrono::duration<double>(Clock::now() - r.received).count();
    write_.set_server_us(latency * 1e6);
    if (entry_->metrics) {
      entry_->metrics->frame(r.result.stats, latency);
      if (r.skipped) entry_->metrics->skipped(r.skipped);
    }
    last_sent_ = std::move(pvs);
    ready_.reset();
    writing_ = true;
    StartWrite(&write_);
  }

  void on_release() {
    if (!entry_) return;
    entry_->viewers.fetch_sub(1, std::memory_order_relaxed);
    if (entry_->metrics) entry_->metrics->viewers(-1);
    if (viewer_added_) {
      // The viewer's claims on its last PVS go with it.
      svc_->pool().submit(client_, [entry = entry_, v = viewer_](Scratch&) {
        if (!entry->deleted.load()) entry->scene->remove_viewer(v);
      });
    }
  }

  v1::ViewRequest read_;                 // Owned by the outstanding read.
  v1::ViewResponse write_;               // Owned by the outstanding write.
  v1::PvsEncoding encoding_ = v1::PVS_FULL;
  bool have_frame_ = false;
  std::uint64_t last_frame_ = 0;
  double last_t_ = 0.0;
  std::optional<Pending> pending_;       // Guarded by mu_.
  std::uint32_t skipped_ = 0;            // Guarded by mu_.
  std::optional<Ready> ready_;           // Guarded by mu_.
  std::vector<ObjectId> last_sent_;      // Guarded by mu_: PVS of the last answer written.
  bool computing_ = false, eof_ = false;  // Guarded by mu_.
  // Touched by this stream's jobs only, one at a time (handed over through mu_).
  bool viewer_added_ = false;
  ViewerId viewer_ = 0;
};

// ---------------------------------------------------------------------------
// Simulate: one backend's moves and the scene's wake list.
//
// One batch is applied at a time, and the next message is read only when the
// previous acknowledgement has been handed to a write, so a backend that does
// not read its answers is slowed down instead of queueing acknowledgements.
// Wake lists are latest-wins: a delta is taken at write time against the
// last list written.

class SimReactor final
    : public StreamReactor<v1::SimulateRequest, v1::SimulateResponse, SimReactor> {
  friend class StreamReactor<v1::SimulateRequest, v1::SimulateResponse, SimReactor>;

 public:
  SimReactor(Service* svc, grpc::CallbackServerContext* ctx) : StreamReactor(svc, "Simulate") {
    sink_ = std::make_shared<WakeSink>();
    sink_->reactor = this;
    const grpc::Status admitted = admit(ctx, Role::Simulation);
    std::lock_guard<std::mutex> lock(mu_);
    if (!admitted.ok()) stop_locked(admitted);
    advance_locked();  // Starts the first read.
  }

  void on_wake(std::shared_ptr<const WakeSnapshot> snap) {
    std::lock_guard<std::mutex> lock(mu_);
    wake_latest_ = std::move(snap);
    advance_locked();
  }

  void OnReadDone(bool ok) override {
    std::lock_guard<std::mutex> lock(mu_);
    reading_ = false;
    if (!ok) {
      eof_ = true;
    } else if (!stopping_) {
      grpc::Status s = accept_locked();
      if (!s.ok()) stop_locked(s);
    }
    advance_locked();
  }

 private:
  void on_done() {
    // From here on the scene delivers nothing to this stream.
    std::lock_guard<std::mutex> lock(sink_->mu);
    sink_->reactor = nullptr;
  }
  void on_stop_locked() {}

  grpc::Status accept_locked() {
    const v1::SimulateRequest& r = read_;
    if (!entry_) {
      if (r.scene_id().empty())
        return invalid(Status::Error("scene_id", "the first message of a stream must name the scene"));
      if (grpc::Status s = check_scene_id(r.scene_id()); !s.ok()) return s;
      entry_ = svc_->find(r.scene_id());
      if (!entry_) return no_scene(r.scene_id());
      entry_->simulators.fetch_add(1, std::memory_order_relaxed);
      ++jobs_;
      entry_->strand->post([this, entry = entry_, sink = sink_](Scratch&) {
        if (!entry->deleted.load()) entry->subscribe(sink);
        job_done(std::nullopt, grpc::Status::OK);
      });
    } else if (!r.scene_id().empty() && r.scene_id() != entry_->id) {
      return invalid(Status::Error("scene_id", "cannot change within a stream (stream is on '" +
                                                   entry_->id + "')"));
    }
    if (!r.has_batch()) return grpc::Status::OK;
    const v1::MoveBatch& b = r.batch();
    if (Status s = validate_time("batch.t", b.t()); !s) return invalid(s);
    if (have_t_ && b.t() < last_t_)
      return invalid(Status::Error("batch.t", "must not decrease along a stream"));
    std::vector<Move> moves;
    if (Status s = moves_from_proto(b, &moves); !s) return invalid(s);
    have_t_ = true;
    last_t_ = b.t();
    applying_ = true;
    ++jobs_;
    entry_->strand->post([this, entry = entry_, seq = b.seq(), t = b.t(),
                          moves = std::move(moves)](Scratch&) {
      apply(*entry, seq, t, moves);
    });
    return grpc::Status::OK;
  }

  // Job of the scene's strand.
  void apply(SceneEntry& e, std::uint64_t seq, double t, const std::vector<Move>& moves) {
    bool stopped;
    {
      std::lock_guard<std::mutex> lock(mu_);
      stopped = stopping_;
    }
    if (stopped) {
      // Nobody will read the acknowledgement: the batch is not applied.
      svc_->count_dropped();
      job_done(std::nullopt, grpc::Status(grpc::StatusCode::CANCELLED, "stream stopped"));
      return;
    }
    if (e.deleted.load()) {
      job_done(std::nullopt, deleted(e));
      return;
    }
    // One batch may advance the clock by a bounded step; the first one on a
    // scene adopts the backend's epoch.
    const double step_limit = svc_->config().max_time_step_s;
    const double from = e.sim_time.load(std::memory_order_relaxed);
    if (e.sim_clock_set && t - from > step_limit) {
      job_done(std::nullopt,
               invalid(Status::Error("batch.t", num(t) + " is " + num(t - from) +
                                                    " s beyond the scene's clock (" + num(from) +
                                                    "); one batch may advance it by at most " +
                                                    num(step_limit) + " s")));
      return;
    }
    Scene& scene = *e.scene;
    MoveReport report;
    Status s = scene.apply_moves(t, moves, &report, Scene::Clock::Latest);
    const double at = report.t;
    if (!s) {
      job_done(std::nullopt, invalid(Status::Error("batch." + s.field, s.message)));
      return;
    }
    e.moves_applied.fetch_add(report.applied, std::memory_order_relaxed);
    store_max(e.time, at);
    store_max(e.sim_time, at);
    e.sim_clock_set = true;
    if (report.applied) e.positions_dirty.store(true, std::memory_order_relaxed);
    if (e.metrics) e.metrics->moves(report.applied);
    e.refresh_wake();
    v1::MoveAck ack;
    ack.set_seq(seq);
    ack.set_applied(report.applied);
    for (ObjectId id : report.too_fast) ack.add_too_fast(id);
    ack.set_t(at);
    job_done(std::move(ack), grpc::Status::OK);
  }

  void job_done(std::optional<v1::MoveAck> ack, const grpc::Status& status) {
    bool del;
    {
      std::lock_guard<std::mutex> lock(mu_);
      if (ack) {
        applying_ = false;
        ack_ = std::move(ack);
      } else if (!status.ok()) {
        applying_ = false;
        stop_locked(status);
      }
      advance_locked();
      del = end_job_locked();
    }
    if (del) release();
  }

  void advance_locked() {
    if (finished_) return;
    if (!writing_) {
      if (ack_) {
        write_.Clear();
        *write_.mutable_ack() = std::move(*ack_);
        ack_.reset();
        writing_ = true;
        StartWrite(&write_);
      } else if (wake_latest_ && wake_latest_ != wake_sent_ && !stopping_) {
        write_.Clear();
        v1::WakeList* w = write_.mutable_wake();
        w->set_version(wake_latest_->version);
        w->set_size(static_cast<std::uint32_t>(wake_latest_->ids.size()));
        if (!wake_sent_) {
          w->set_full(true);
          add_ids(wake_latest_->ids, w->mutable_ids());
        } else {
          difference(wake_latest_->ids, wake_sent_->ids, w->mutable_woken());
          difference(wake_sent_->ids, wake_latest_->ids, w->mutable_slept());
        }
        wake_sent_ = wake_latest_;
        writing_ = true;
        StartWrite(&write_);
      }
    }
    if (!reading_ && !eof_ && !stopping_ && !applying_ && !ack_) {
      reading_ = true;
      StartRead(&read_);
    }
    const bool idle = !writing_ && !applying_ && !ack_;
    if (idle && (stopping_ || eof_)) finish_locked();
  }

  void on_release() {
    if (!entry_) return;
    entry_->simulators.fetch_sub(1, std::memory_order_relaxed);
    entry_->unsubscribe(sink_);
  }

  std::shared_ptr<WakeSink> sink_;
  v1::SimulateRequest read_;
  v1::SimulateResponse write_;
  bool have_t_ = false;
  double last_t_ = 0.0;
  std::optional<v1::MoveAck> ack_;     // Guarded by mu_: acknowledgement waiting to be written.
  std::shared_ptr<const WakeSnapshot> wake_latest_, wake_sent_;  // Guarded by mu_.
  bool reading_ = false, applying_ = false, eof_ = false;  // Guarded by mu_.
};

void deliver_wake(SimReactor* r, std::shared_ptr<const WakeSnapshot> snap) {
  r->on_wake(std::move(snap));
}

// ---------------------------------------------------------------------------
// Service

Service::Service(ServiceConfig config, WorkerPool& pool, SceneStore& store,
                 const TokenTable& tokens, Metrics& metrics, Log log)
    : config_(std::move(config)),
      pool_(pool),
      store_(store),
      tokens_(tokens),
      metrics_(metrics),
      log_(std::move(log)) {}

Service::~Service() = default;

std::shared_ptr<SceneEntry> Service::find(const std::string& id) const {
  std::lock_guard<std::mutex> lock(scenes_mu_);
  auto it = scenes_.find(id);
  return it == scenes_.end() ? nullptr : it->second;
}

bool Service::has_scene(const std::string& id) const { return find(id) != nullptr; }

bool Service::add_stream(Stream* s) {
  std::lock_guard<std::mutex> lock(streams_mu_);
  if (shutting_down_) return false;
  streams_.insert(s);
  return true;
}

void Service::remove_stream(Stream* s) {
  std::lock_guard<std::mutex> lock(streams_mu_);
  streams_.erase(s);
}

void Service::begin_shutdown() {
  std::lock_guard<std::mutex> lock(streams_mu_);
  shutting_down_ = true;
  stopping_.store(true);
  for (Stream* s : streams_) s->stop_if(nullptr, shutting_down_status());
}

void Service::count_error(const char* method, const grpc::Status& status) {
  metrics_.error(method, status.error_code());
}

void Service::finish_unary(grpc::ServerUnaryReactor* r, const char* method, const grpc::Status& s) {
  if (!s.ok()) count_error(method, s);
  r->Finish(s);
}

std::shared_ptr<SceneEntry> Service::find_or_finish(grpc::ServerUnaryReactor* r, const char* method,
                                                    const std::string& id) {
  if (grpc::Status s = check_scene_id(id); !s.ok()) {
    finish_unary(r, method, s);
    return nullptr;
  }
  std::shared_ptr<SceneEntry> e = find(id);
  if (!e) finish_unary(r, method, no_scene(id));
  return e;
}

void Service::fill_info(const SceneEntry& e, v1::SceneInfo* out) const {
  out->set_scene_id(e.id);
  out->mutable_grid()->set_nx(static_cast<std::uint32_t>(e.grid.res.x));
  out->mutable_grid()->set_ny(static_cast<std::uint32_t>(e.grid.res.y));
  out->mutable_grid()->set_nz(static_cast<std::uint32_t>(e.grid.res.z));
  vec_to_proto(e.grid.bounds_min, out->mutable_bounds_min());
  vec_to_proto(e.grid.bounds_max, out->mutable_bounds_max());
  out->set_objects(e.objects);
  out->set_dynamic_objects(e.dynamic_objects);
  out->set_time(e.time.load());
  out->set_viewers(e.viewers.load());
  out->set_simulators(e.simulators.load());
  out->set_frames_served(e.frames_served.load());
  out->set_moves_applied(e.moves_applied.load());
  out->set_tbvs_active(e.tbvs_active.load());
  out->set_wake_size(e.wake_size.load());
  out->set_memory_bytes(e.memory_bytes);
}

grpc::Status Service::build_scene(const std::string& id, SceneDesc desc, const std::string& json,
                                  bool from_json, bool persist) {
  const SceneOptions& opt = config_.scene_options;
  const glm::ivec3 res = desc.grid ? *desc.grid : Scene::auto_resolution(desc, opt);
  const std::int64_t voxels = std::int64_t{res.x} * res.y * res.z;
  if (voxels > opt.max_voxels)
    return grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED,
                        "grid: " + std::to_string(voxels) + " voxels exceed the limit of " +
                            std::to_string(opt.max_voxels));
  const std::uint64_t bytes = estimate_scene_bytes(desc, res, config_.workers);
  {
    std::lock_guard<std::mutex> lock(scenes_mu_);
    if (deleting_.count(id))
      return grpc::Status(grpc::StatusCode::ABORTED,
                          "scene_id: '" + id + "' is being deleted; try again");
    if (scenes_.count(id) || reserved_.count(id))
      return grpc::Status(grpc::StatusCode::ALREADY_EXISTS, "scene_id: '" + id + "' exists");
    if (bytes_in_use_ + bytes > config_.memory_budget_bytes)
      return grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED,
                          "scene needs about " + mib(bytes) + " at grid " +
                              std::to_string(res.x) + "x" + std::to_string(res.y) + "x" +
                              std::to_string(res.z) + "; memory budget " +
                              mib(config_.memory_budget_bytes) + ", " + mib(bytes_in_use_) +
                              " in use");
    reserved_[id] = bytes;
    bytes_in_use_ += bytes;
  }
  auto unreserve = [&](bool keep_bytes) {
    std::lock_guard<std::mutex> lock(scenes_mu_);
    reserved_.erase(id);
    if (!keep_bytes) bytes_in_use_ -= bytes;
  };

  auto entry = std::make_shared<SceneEntry>();
  Status s = Scene::create(desc, opt, &entry->scene);
  if (!s) {
    unreserve(false);
    return invalid(scene_create_error(s, from_json, json));
  }
  if (persist) {
    if (Status w = store_.save_scene(id, json); !w) {
      unreserve(false);
      return grpc::Status(grpc::StatusCode::INTERNAL, "cannot store the scene: " + w.str());
    }
  }
  entry->id = id;
  entry->strand = std::make_shared<Strand>(pool_, "scene:" + id);
  entry->memory_bytes = bytes;
  entry->grid = entry->scene->grid();
  entry->objects = static_cast<std::uint32_t>(entry->scene->object_count());
  entry->dynamic_objects = static_cast<std::uint32_t>(entry->scene->dynamic_count());
  entry->time.store(entry->scene->time());
  entry->metrics = metrics_.scene(id);
  entry->refresh_wake();
  entry->tbvs_active.store(0);
  std::size_t count;
  {
    std::lock_guard<std::mutex> lock(scenes_mu_);
    reserved_.erase(id);
    scenes_[id] = entry;
    count = scenes_.size();
  }
  metrics_.scenes(count);
  return grpc::Status::OK;
}

Status Service::load_scene(const std::string& id, const std::string& json,
                           const std::string& source, const std::vector<Move>* positions,
                           std::optional<double> t, bool persist) {
  SceneDesc desc;
  FormatError err;
  if (!parse_scene(json, source, &desc, &err)) return Status::Error("", err.str());
  // Checked before the scene is registered, so that applying it cannot fail.
  if (t) {
    if (Status s = validate_time("t", *t); !s) return Status::Error("", source + ": saved time: " + s.str());
  }
  if (positions) {
    std::map<ObjectId, Vec3> at;
    for (const Move& m : *positions) at[m.id] = m.center;
    for (ObjectDesc& o : desc.objects) {
      auto it = at.find(o.id);
      if (o.dynamic && it != at.end()) o.center = it->second;
    }
  }
  grpc::Status g = build_scene(id, std::move(desc), json, true, persist);
  if (!g.ok()) return Status::Error("", source + ": " + g.error_message());
  if (t) {
    // Nothing serves the scene yet: the strand's fields are ours here.
    std::shared_ptr<SceneEntry> e = find(id);
    e->scene->apply_moves(*t, {});
    e->time.store(*t);
    e->sim_time.store(*t);
    e->sim_clock_set = true;
  }
  return Status::Ok();
}

void Service::save_positions() {
  std::vector<std::shared_ptr<SceneEntry>> entries;
  {
    std::lock_guard<std::mutex> lock(scenes_mu_);
    for (auto& [id, e] : scenes_)
      if (e->dynamic_objects > 0 && e->positions_dirty.load()) entries.push_back(e);
  }
  for (const auto& e : entries) {
    e->positions_dirty.store(false);
    double t = 0.0;
    const std::vector<Move> centers = e->scene->dynamic_centers(&t);
    std::lock_guard<std::mutex> lock(store_mu_);
    if (e->deleted.load()) continue;
    if (Status s = store_.save_positions(e->id, t, centers); !s) {
      e->positions_dirty.store(true);  // Try again next period.
      log_("cannot save positions of scene '" + e->id + "': " + s.str());
    }
  }
}

// --- RPCs ------------------------------------------------------------------

grpc::ServerUnaryReactor* Service::CreateScene(grpc::CallbackServerContext* ctx,
                                               const v1::CreateSceneRequest* req,
                                               v1::SceneInfo* resp) {
  grpc::ServerUnaryReactor* r = ctx->DefaultReactor();
  if (grpc::Status a = tokens_.authorize(ctx, Role::Admin); !a.ok()) {
    finish_unary(r, "CreateScene", a);
    return r;
  }
  if (grpc::Status s = check_scene_id(req->scene_id()); !s.ok()) {
    finish_unary(r, "CreateScene", s);
    return r;
  }
  // Parsing and building a grid take long: off the callback thread.
  pool_.submit(ctx->peer(), [this, r, req, resp](Scratch&) {
    if (shutting_down()) {
      count_dropped();
      finish_unary(r, "CreateScene", shutting_down_status());
      return;
    }
    SceneDesc desc;
    std::string json;
    bool from_json = false;
    Status s;
    switch (req->content_case()) {
      case v1::CreateSceneRequest::kDescription:
        s = desc_from_proto(req->description(), &desc);
        if (s) json = scene_to_json(desc);
        break;
      case v1::CreateSceneRequest::kSceneJson:
        from_json = true;
        json = req->scene_json();
        s = desc_from_json(json, &desc);
        break;
      default:
        s = Status::Error("content", "missing: set description or scene_json");
    }
    if (!s) {
      finish_unary(r, "CreateScene", invalid(s));
      return;
    }
    grpc::Status g = build_scene(req->scene_id(), std::move(desc), json, from_json, true);
    if (g.ok()) {
      fill_info(*find(req->scene_id()), resp);
      log_("created scene '" + req->scene_id() + "'");
    }
    finish_unary(r, "CreateScene", g);
  });
  return r;
}

grpc::ServerUnaryReactor* Service::DeleteScene(grpc::CallbackServerContext* ctx,
                                               const v1::DeleteSceneRequest* req,
                                               v1::DeleteSceneResponse* /*resp*/) {
  grpc::ServerUnaryReactor* r = ctx->DefaultReactor();
  if (grpc::Status a = tokens_.authorize(ctx, Role::Admin); !a.ok()) {
    finish_unary(r, "DeleteScene", a);
    return r;
  }
  if (grpc::Status s = check_scene_id(req->scene_id()); !s.ok()) {
    finish_unary(r, "DeleteScene", s);
    return r;
  }
  // The id stays taken (deleting_) until the scene's files and metrics are
  // gone, so that a CreateScene of the same id cannot interleave with the
  // removal and lose its files or its metric series.
  std::shared_ptr<SceneEntry> e;
  std::size_t count;
  {
    std::lock_guard<std::mutex> lock(scenes_mu_);
    auto it = scenes_.find(req->scene_id());
    if (it != scenes_.end()) {
      e = it->second;
      scenes_.erase(it);
      bytes_in_use_ -= e->memory_bytes;
      deleting_.insert(e->id);
    }
    count = scenes_.size();
  }
  if (!e) {
    finish_unary(r, "DeleteScene", no_scene(req->scene_id()));
    return r;
  }
  Status removed;
  {
    std::lock_guard<std::mutex> lock(store_mu_);
    e->deleted.store(true);
    removed = store_.remove_scene(e->id);
  }
  {
    std::lock_guard<std::mutex> lock(streams_mu_);
    for (Stream* s : streams_)
      s->stop_if(e.get(), deleted(*e));
  }
  metrics_.remove_scene(e->id);
  metrics_.scenes(count);
  {
    std::lock_guard<std::mutex> lock(scenes_mu_);
    deleting_.erase(e->id);
  }
  if (!removed) {
    log_("scene '" + e->id + "' deleted but its files remain: " + removed.str());
    finish_unary(r, "DeleteScene",
                 grpc::Status(grpc::StatusCode::INTERNAL, "cannot remove the scene's files: " + removed.str()));
    return r;
  }
  log_("deleted scene '" + e->id + "'");
  finish_unary(r, "DeleteScene", grpc::Status::OK);
  return r;
}

grpc::ServerUnaryReactor* Service::ListScenes(grpc::CallbackServerContext* ctx,
                                              const v1::ListScenesRequest* /*req*/,
                                              v1::ListScenesResponse* resp) {
  grpc::ServerUnaryReactor* r = ctx->DefaultReactor();
  if (grpc::Status a = tokens_.authorize(ctx, Role::Viewer); !a.ok()) {
    finish_unary(r, "ListScenes", a);
    return r;
  }
  std::vector<std::shared_ptr<SceneEntry>> entries;
  {
    std::lock_guard<std::mutex> lock(scenes_mu_);
    for (auto& [id, e] : scenes_) entries.push_back(e);
  }
  for (const auto& e : entries) fill_info(*e, resp->add_scenes());
  finish_unary(r, "ListScenes", grpc::Status::OK);
  return r;
}

grpc::ServerUnaryReactor* Service::GetSceneStats(grpc::CallbackServerContext* ctx,
                                                 const v1::GetSceneStatsRequest* req,
                                                 v1::SceneInfo* resp) {
  grpc::ServerUnaryReactor* r = ctx->DefaultReactor();
  if (grpc::Status a = tokens_.authorize(ctx, Role::Viewer); !a.ok()) {
    finish_unary(r, "GetSceneStats", a);
    return r;
  }
  std::shared_ptr<SceneEntry> e = find_or_finish(r, "GetSceneStats", req->scene_id());
  if (!e) return r;
  fill_info(*e, resp);
  finish_unary(r, "GetSceneStats", grpc::Status::OK);
  return r;
}

grpc::ServerUnaryReactor* Service::GetPvs(grpc::CallbackServerContext* ctx,
                                          const v1::GetPvsRequest* req, v1::GetPvsResponse* resp) {
  grpc::ServerUnaryReactor* r = ctx->DefaultReactor();
  if (grpc::Status a = tokens_.authorize(ctx, Role::Viewer); !a.ok()) {
    finish_unary(r, "GetPvs", a);
    return r;
  }
  std::shared_ptr<SceneEntry> e = find_or_finish(r, "GetPvs", req->scene_id());
  if (!e) return r;
  Camera camera;
  if (Status s = camera_from_proto(req->camera(), req->has_camera(), &camera); !s) {
    finish_unary(r, "GetPvs", invalid(s));
    return r;
  }
  if (Status s = validate_time("t", req->t()); !s) {
    finish_unary(r, "GetPvs", invalid(s));
    return r;
  }
  const Clock::time_point received = Clock::now();
  pool_.submit(ctx->peer(), [this, ctx, r, e, camera, t = req->t(), resp, received](Scratch& scratch) {
    // Work nobody waits for any more is answered without running.
    if (ctx->IsCancelled()) {
      count_dropped();
      r->Finish(grpc::Status(grpc::StatusCode::CANCELLED, "cancelled"));
      return;
    }
    if (shutting_down()) {
      count_dropped();
      finish_unary(r, "GetPvs", shutting_down_status());
      return;
    }
    if (e->deleted.load()) {
      finish_unary(r, "GetPvs", deleted(*e));
      return;
    }
    Scene& scene = *e->scene;
    const ViewerId v = scene.add_viewer();
    FrameResult result;
    Status s = scene.frame(v, camera, e->view_time(t, config_.max_view_lead_s), scratch, &result,
                           Scene::Clock::Latest);
    scene.remove_viewer(v);
    if (!s) {
      finish_unary(r, "GetPvs", invalid(s));
      return;
    }
    e->after_frame(result);
    add_ids(result.pvs, resp->mutable_pvs());
    stats_to_proto(result.stats, resp->mutable_stats());
    resp->set_t(result.t);
    if (e->metrics)
      e->metrics->frame(result.stats, std::chrono::duration<double>(Clock::now() - received).count());
    finish_unary(r, "GetPvs", grpc::Status::OK);
  });
  return r;
}

grpc::ServerBidiReactor<v1::ViewRequest, v1::ViewResponse>* Service::View(
    grpc::CallbackServerContext* ctx) {
  return new ViewReactor(this, ctx);
}

grpc::ServerBidiReactor<v1::SimulateRequest, v1::SimulateResponse>* Service::Simulate(
    grpc::CallbackServerContext* ctx) {
  return new SimReactor(this, ctx);
}

}  // namespace voxvis::server
