// stream_reactor.h — what the streaming calls (View, Simulate and Tick;
// streams.h) share: admission, raw messages, stopping and lifetime, and the
// sink through which a stream gets its scene's wake list.
#pragma once

#include <atomic>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <utility>

#include <grpcpp/grpcpp.h>

#include "scenes/scene_entry.h"
#include "serving/admission.h"
#include "serving/serving.h"
#include "wire/calls.h"
#include "wire/convert.h"

namespace voxvis::server {

/// A stream's end of its scene's wake list (WakeSink, scene_entry.h), the
/// one way Simulate and Tick streams get it: keeps the latest list, and
/// hands each change to `on_change` when given (Simulate writes every
/// change at once; Tick writes latest() with its next answer). Subscribed
/// from a job of the scene's strand, never a reaction: subscribing reads the
/// engine's wake set. `on_change` runs under the scene's wake lock and this
/// sink's; detach() before the stream goes.
class StreamWakeSink final : public WakeSink {
 public:
  using OnChange = std::function<void(const std::shared_ptr<const WakeSnapshot>&)>;
  explicit StreamWakeSink(OnChange on_change = {}) : on_change_(std::move(on_change)) {}
  void wake_changed(std::shared_ptr<const WakeSnapshot> snap) override {
    std::lock_guard<std::mutex> lock(mu_);
    latest_ = std::move(snap);
    if (on_change_) on_change_(latest_);
  }
  /// The list last handed over; null before the subscription.
  std::shared_ptr<const WakeSnapshot> latest() {
    std::lock_guard<std::mutex> lock(mu_);
    return latest_;
  }
  /// From here on `on_change` is not called (the stream is going).
  void detach() {
    std::lock_guard<std::mutex> lock(mu_);
    on_change_ = nullptr;
  }

 private:
  std::mutex mu_;
  OnChange on_change_;                          // Guarded by mu_.
  std::shared_ptr<const WakeSnapshot> latest_;  // Guarded by mu_.
};

// ---------------------------------------------------------------------------
// What both streams share: admission (token, registration for shutdown), raw
// messages parsed here (bytes that are not a Req end the stream with
// INVALID_ARGUMENT), the stop-then-finish protocol, and a lifetime that
// outlasts gRPC's OnDone until the last pool job referencing the stream has
// ended. `Self` provides on_read_locked() (a message or the client's
// half-close), advance_locked() (writes, reads, Finish), on_stop_locked() and
// on_done() (hooks), and on_release() (called once, just before deletion).

template <class Req, class Resp, class Self>
class StreamReactor : public grpc::ServerBidiReactor<grpc::ByteBuffer, grpc::ByteBuffer>,
                      public Stream {
 public:
  void OnReadDone(bool ok) override {
    std::lock_guard<std::mutex> lock(mu_);
    grpc::Status parsed;
    if (ok && !parse_message(in_, &read_.fresh()))
      parsed = malformed(Req::descriptor()->full_name(), in_.Length());
    self().on_read_locked(ok, parsed);
  }

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
    leave_call();  // Nobody waits for this stream any more.
    std::lock_guard<std::mutex> lock(mu_);
    stop_locked(grpc::Status(grpc::StatusCode::CANCELLED, "cancelled"));
    self().advance_locked();
  }

  void OnDone() override {
    if (registered_) admission_.remove_stream(this);
    leave_call();
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
  StreamReactor(Admission& admission, Serving& serving, const char* method)
      : admission_(admission), serving_(serving), method_(method) {}

  /// Checks the call's token and registers the stream. Call from the
  /// derived constructor without holding mu_ (the service's stream lock comes
  /// first in the lock order).
  grpc::Status admit(grpc::CallbackServerContext* ctx, Role role) {
    client_ = ctx->peer();
    const grpc::Status auth = admission_.authorize(ctx, role);
    registered_ = admission_.add_stream(this);
    if (!auth.ok()) return auth;
    if (!registered_) return shutting_down_status();
    const grpc::Status busy = admission_.enter_call();
    in_call_ = busy.ok();
    return busy;
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
    if (!s.ok() && s.error_code() != grpc::StatusCode::CANCELLED) admission_.count_error(method_, s);
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

  void start_read() { StartRead(&in_); }

  /// Gives back the stream's place among the calls in progress, once.
  void leave_call() {
    if (in_call_ && !left_call_.exchange(true)) admission_.leave_call();
  }

  /// The scene id of a message: the first must name a valid one, later ones
  /// may repeat it or leave it empty.
  grpc::Status check_scene_field_locked(const std::string& id) const {
    if (entry_) {
      if (id.empty() || id == entry_->id) return grpc::Status::OK;
      return invalid(Status::Error("scene_id", "cannot change within a stream (stream is on '" +
                                                   entry_->id + "')"));
    }
    if (id.empty())
      return invalid(Status::Error("scene_id", "the first message of a stream must name the scene"));
    return check_scene_id(id);
  }

  /// The end of a constructor for a stream that reads at once: the first
  /// read, or the refusal of `admitted`.
  void open_locked(const grpc::Status& admitted) {
    if (admitted.ok()) {
      start_read();
    } else {
      stop_locked(admitted);
    }
    self().advance_locked();
  }

  /// A PVS stream's message (View, Tick): the scene (the first message's
  /// becomes the stream's, with its `encoding`; `*first` says it was), then
  /// `number` (the field `number_field`) increasing and the time `t` valid
  /// and not decreasing along the stream.
  grpc::Status accept_sequence_locked(const std::string& scene_id, int encoding, bool* first,
                                      const char* number_field, std::uint64_t number, double t) {
    *first = false;
    if (grpc::Status s = check_scene_field_locked(scene_id); !s.ok()) return s;
    if (!entry_) {
      if (encoding != v1::PVS_FULL && encoding != v1::PVS_DELTA)
        return invalid(Status::Error("encoding", "unknown value " + std::to_string(encoding)));
      if (grpc::Status s = find_scene_locked(scene_id); !s.ok()) return s;
      encoding_ = static_cast<v1::PvsEncoding>(encoding);
      *first = true;
    }
    if (have_number_ && number <= last_number_)
      return invalid(Status::Error(number_field, "must increase along a stream: " + std::to_string(number) +
                                                     " after " + std::to_string(last_number_)));
    if (Status s = validate_time("t", t); !s) return invalid(s);
    if (have_number_ && t < last_t_) return invalid(Status::Error("t", "must not decrease along a stream"));
    return grpc::Status::OK;
  }
  /// Records a message accept_sequence_locked let through.
  void sequence_taken_locked(std::uint64_t number, double t) {
    have_number_ = true;
    last_number_ = number;
    last_t_ = t;
  }

  /// Makes the first message's scene the stream's.
  grpc::Status find_scene_locked(const std::string& id) {
    entry_ = serving_.find(id);
    return entry_ ? grpc::Status::OK : serving_.missing(id);
  }

  /// Writes write_ (one write in flight: the caller checked writing_).
  void start_write_locked() {
    if (grpc::Status s = serialize_message(write_.get(), &out_); !s.ok()) {
      stop_locked(s);
      return;
    }
    writing_ = true;
    StartWrite(&out_);
  }

  Admission& admission_;
  Serving& serving_;
  const char* method_;
  std::string client_;       // The connection's peer: the pool's admission key. Set in admit.
  bool registered_ = false;  // Written before any reaction can run.
  bool in_call_ = false;     // Took a place among the calls in progress; as registered_.
  std::atomic<bool> left_call_{false};
  std::mutex mu_;
  std::shared_ptr<SceneEntry> entry_;  // Guarded by mu_; set by the first message.
  bool writing_ = false, stopping_ = false, finished_ = false, done_ = false;  // Guarded by mu_.
  grpc::Status stop_status_;           // Guarded by mu_.
  int jobs_ = 0;                       // Guarded by mu_: pool jobs referencing this.
  ReusedMessage<Req> read_;            // The last message read: read_.get().
  v1::PvsEncoding encoding_ = v1::PVS_FULL;  // Guarded by mu_: a PVS stream's, from its first message.
  bool have_number_ = false;           // Guarded by mu_: accept_sequence_locked's.
  std::uint64_t last_number_ = 0;
  double last_t_ = 0.0;
  ReusedMessage<Resp> write_;          // The message being written: write_.fresh() to make it.

 private:
  grpc::ByteBuffer in_;   // Owned by the outstanding read.
  grpc::ByteBuffer out_;  // Owned by the outstanding write.
  Self& self() { return static_cast<Self&>(*this); }
};

}  // namespace voxvis::server
