// simulate_stream.cpp — the Simulate stream (streams.h): one backend's moves
// and the scene's wake list.
//
// One batch is applied at a time, and the next message is read only when the
// previous acknowledgement has been handed to a write, so a backend that does
// not read its answers is slowed down instead of queueing acknowledgements.
// Wake lists are latest-wins: a delta is taken at write time against the
// last list written.
#include <memory>
#include <mutex>
#include <optional>
#include <utility>
#include <vector>

#include "rpc/stream_reactor.h"
#include "rpc/streams.h"
#include "wire/calls.h"
#include "wire/convert.h"
#include "wire/ids.h"

namespace voxvis::server {
namespace {

class SimReactor final
    : public StreamReactor<v1::SimulateRequest, v1::SimulateResponse, SimReactor> {
  friend class StreamReactor<v1::SimulateRequest, v1::SimulateResponse, SimReactor>;

 public:
  SimReactor(Admission& admission, Serving& serving, grpc::CallbackServerContext* ctx)
      : StreamReactor(admission, serving, "Simulate") {
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
      admission_.count_dropped();
      job_done(std::nullopt, grpc::Status(grpc::StatusCode::CANCELLED, "stream stopped"));
      return;
    }
    if (e.deleted.load()) {
      job_done(std::nullopt, deleted(e.id));
      return;
    }
    MoveReport report;
    if (const grpc::Status g = serving_.apply_batch(e, t, moves, "batch.", &report); !g.ok()) {
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

}  // namespace

grpc::ServerBidiReactor<grpc::ByteBuffer, grpc::ByteBuffer>* new_simulate_stream(
    Admission& admission, Serving& serving, grpc::CallbackServerContext* ctx) {
  return new SimReactor(admission, serving, ctx);
}

}  // namespace voxvis::server
