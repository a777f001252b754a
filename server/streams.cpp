// streams.cpp — the two streaming calls, View (a viewer's frames) and
// Simulate (a backend's moves and the scene's wake list), as callback
// reactors. Their shared base handles admission, raw messages, stopping and
// lifetime; the Service serves their frames (Service::serve_frame) and its
// SceneRegistry keeps the scenes they work on.
#include "streams.h"

#include <atomic>
#include <chrono>
#include <cmath>
#include <memory>
#include <mutex>
#include <optional>
#include <utility>
#include <vector>

#include "calls.h"
#include "convert.h"
#include "frame_answer.h"
#include "ids.h"
#include "stream_reactor.h"

namespace voxvis::server {
namespace {

using Clock = std::chrono::steady_clock;

}  // namespace

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
    open_locked(admitted);
  }

 private:
  void on_read_locked(bool ok, const grpc::Status& parsed) {
    if (!ok) {
      eof_ = true;
    } else if (!stopping_) {
      const grpc::Status s = parsed.ok() ? accept_locked() : parsed;
      if (s.ok()) {
        start_read();
      } else {
        stop_locked(s);
      }
    }
    advance_locked();
  }

  struct Pending {
    std::uint64_t frame = 0;
    double t = 0.0;
    Camera camera;
    Clock::time_point received;
  };
  struct Ready {
    std::uint64_t frame = 0;
    FrameResult result;
    Clock::time_point received;
    std::uint32_t skipped = 0;
  };

  grpc::Status accept_locked() {
    const v1::ViewRequest& r = read_.get();
    bool first = false;
    const grpc::Status seq = accept_sequence_locked(r.scene_id(), r.encoding(), &first, "frame", r.frame(), r.t());
    if (first) {
      // entry_ set means counted as a viewer (released in on_release).
      entry_->viewers.fetch_add(1, std::memory_order_relaxed);
      if (entry_->metrics) entry_->metrics->viewers(+1);
    }
    if (!seq.ok()) return seq;
    Pending p;
    if (Status s = camera_from_proto(r.camera(), r.has_camera(), &p.camera); !s) return invalid(s);
    sequence_taken_locked(r.frame(), r.t());
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
    if (!writing_ && ready_full_) write_locked();
    if (!stopping_ && !computing_ && pending_ && !ready_full_) {
      computing_ = true;
      ++jobs_;
      job_ = *pending_;
      pending_.reset();
      job_skipped_ = skipped_;
      skipped_ = 0;
      // Frames of one scene run in parallel (the Scene synchronizes itself);
      // this stream's frames one at a time. [this] fits the job's own
      // storage: no allocation a frame. The stream outlives its jobs
      // (jobs_), and entry_ is fixed by now.
      svc_->pool().submit(client_, [this](Scratch& scratch) { compute(*entry_, scratch); });
    }
    const bool idle = !writing_ && !computing_ && !ready_full_;
    if (idle && (stopping_ || (eof_ && !pending_))) finish_locked();
  }

  // Pool job: the frame of job_, into computed_ (both this job's alone until
  // it hands computed_ over under mu_, trading places with the empty ready_,
  // so that the answers' buffers go round and a frame allocates nothing).
  void compute(SceneEntry& e, Scratch& scratch) {
    std::optional<FrameResult> check;  // Verify mode: a copy of the frame served.
    grpc::Status error;
    bool stopped;
    {
      std::lock_guard<std::mutex> lock(mu_);
      stopped = stopping_;
    }
    bool served = false;
    if (stopped) {
      // Cancelled, shut down or deleted while queued: nobody waits for it.
      svc_->count_dropped();
    } else {
      computed_.frame = job_.frame;
      computed_.received = job_.received;
      computed_.skipped = job_skipped_;
      bool sampled = false;
      error = svc_->serve_frame(e, &viewer_, job_.camera, job_.t, scratch, &computed_.result, &sampled);
      served = error.ok();
      if (served && sampled) check.emplace(computed_.result);
    }
    // Once mu_ is released another thread may end and delete this stream
    // (unless `del` says this job is the last): what the check needs after
    // it is copied first, the scene held by `keep`.
    Service* const svc = svc_;
    const std::shared_ptr<SceneEntry> keep = check ? entry_ : nullptr;
    const std::uint64_t frame = job_.frame;
    const Camera camera = job_.camera;
    const std::string viewer = check ? client_ + " viewer " + std::to_string(viewer_.id) : std::string();
    bool del;
    {
      std::lock_guard<std::mutex> lock(mu_);
      computing_ = false;
      if (served) {
        std::swap(ready_, computed_);
        ready_full_ = true;
      } else if (!error.ok()) {
        stop_locked(error);
      }
      advance_locked();
      del = end_job_locked();
    }
    // The answer is handed over; the check runs on the verifier's thread.
    if (check) svc->verify_served(*keep, viewer, frame, camera, *check);
    if (del) release();
  }

  void write_locked() {
    Ready& r = ready_;
    auto& w = write_.fresh();
    w.set_frame(r.frame);
    w.set_encoding(encoding_);
    w.set_frames_skipped(r.skipped);
    const double latency = std::chrono::duration<double>(Clock::now() - r.received).count();
    w.set_server_us(latency * 1e6);
    answer_frame(*entry_, r.result, encoding_, &last_sent_, latency, &w);
    if (entry_->metrics && r.skipped) entry_->metrics->skipped(r.skipped);
    ready_full_ = false;
    start_write_locked();
  }

  void on_release() {
    if (!entry_) return;
    entry_->viewers.fetch_sub(1, std::memory_order_relaxed);
    if (entry_->metrics) entry_->metrics->viewers(-1);
    svc_->release_viewer(client_, entry_, viewer_);
  }

  std::optional<Pending> pending_;       // Guarded by mu_.
  std::uint32_t skipped_ = 0;            // Guarded by mu_.
  Pending job_;                          // The frame computing: set under mu_, then its job's alone.
  std::uint32_t job_skipped_ = 0;        // The same.
  Ready computed_;                       // The computing job's answer (see compute).
  Ready ready_;                          // Guarded by mu_: the answer waiting, when ready_full_.
  bool ready_full_ = false;              // Guarded by mu_.
  std::vector<ObjectId> last_sent_;      // Guarded by mu_: PVS of the last answer written.
  bool computing_ = false, eof_ = false;  // Guarded by mu_.
  FrameViewer viewer_;  // Touched by this stream's jobs only, one at a time (handed over through mu_).
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
    sink_ = std::make_shared<StreamWakeSink>([this](const auto& snap) { on_wake(snap); });
    const grpc::Status admitted = admit(ctx, Role::Simulation);
    std::lock_guard<std::mutex> lock(mu_);
    if (!admitted.ok()) stop_locked(admitted);
    advance_locked();  // Starts the first read.
  }


 private:
  void on_wake(const std::shared_ptr<const WakeSnapshot>& snap) {
    std::lock_guard<std::mutex> lock(mu_);
    wake_latest_ = snap;
    advance_locked();
  }

  void on_read_locked(bool ok, const grpc::Status& parsed) {
    reading_ = false;
    if (!ok) {
      eof_ = true;
    } else if (!stopping_) {
      const grpc::Status s = parsed.ok() ? accept_locked() : parsed;
      if (!s.ok()) stop_locked(s);
    }
    advance_locked();
  }

  void on_done() {
    // From here on the scene delivers nothing to this stream.
    sink_->detach();
  }
  void on_stop_locked() {}

  grpc::Status accept_locked() {
    const v1::SimulateRequest& r = read_.get();
    if (grpc::Status s = check_scene_field_locked(r.scene_id()); !s.ok()) return s;
    if (!entry_) {
      if (grpc::Status s = find_scene_locked(r.scene_id()); !s.ok()) return s;
      entry_->simulators.fetch_add(1, std::memory_order_relaxed);
      ++jobs_;
      entry_->strand->post([this, entry = entry_, sink = sink_](Scratch&) {
        if (!entry->deleted.load()) entry->subscribe(sink);
        job_done(std::nullopt, grpc::Status::OK);
      });
    }
    if (!r.has_batch()) return grpc::Status::OK;
    const v1::MoveBatch& b = r.batch();
    if (Status s = validate_time("batch.t", b.t()); !s) return invalid(s);
    if (have_batch_t_ && b.t() < last_batch_t_)
      return invalid(Status::Error("batch.t", "must not decrease along a stream"));
    std::vector<Move> moves;
    if (Status s = moves_from_proto(b, &moves); !s) return invalid(s);
    have_batch_t_ = true;
    last_batch_t_ = b.t();
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
    MoveReport report;
    if (const grpc::Status g = svc_->apply_batch(e, t, moves, "batch.", &report); !g.ok()) {
      job_done(std::nullopt, g);
      return;
    }
    const double at = report.t;
    v1::MoveAck ack;
    ack.set_seq(seq);
    ack.set_applied(report.applied);
    put_ids(report.too_fast, ack.mutable_too_fast());
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
        auto& w = write_.fresh();
        *w.mutable_ack() = std::move(*ack_);
        ack_.reset();
        start_write_locked();
      } else if (wake_latest_ && wake_latest_ != wake_sent_ && !stopping_) {
        auto& w = write_.fresh();
        put_wake(wake_latest_->version, wake_latest_->ids, wake_sent_ ? &wake_sent_->ids : nullptr, w.mutable_wake());
        wake_sent_ = wake_latest_;
        start_write_locked();
      }
    }
    if (!reading_ && !eof_ && !stopping_ && !applying_ && !ack_) {
      reading_ = true;
      start_read();
    }
    const bool idle = !writing_ && !applying_ && !ack_;
    if (idle && (stopping_ || eof_)) finish_locked();
  }

  void on_release() {
    if (!entry_) return;
    entry_->simulators.fetch_sub(1, std::memory_order_relaxed);
    entry_->unsubscribe(sink_);
  }

  std::shared_ptr<StreamWakeSink> sink_;
  bool have_batch_t_ = false;
  double last_batch_t_ = 0.0;
  std::optional<v1::MoveAck> ack_;     // Guarded by mu_: acknowledgement waiting to be written.
  std::shared_ptr<const WakeSnapshot> wake_latest_, wake_sent_;  // Guarded by mu_.
  bool reading_ = false, applying_ = false, eof_ = false;  // Guarded by mu_.
};

grpc::ServerBidiReactor<grpc::ByteBuffer, grpc::ByteBuffer>* new_view_stream(
    Service* svc, grpc::CallbackServerContext* ctx) {
  return new ViewReactor(svc, ctx);
}

grpc::ServerBidiReactor<grpc::ByteBuffer, grpc::ByteBuffer>* new_simulate_stream(
    Service* svc, grpc::CallbackServerContext* ctx) {
  return new SimReactor(svc, ctx);
}

}  // namespace voxvis::server
