// view_stream.cpp — the View stream (streams.h): one viewer's frames.
//
// State machine (all under mu_): a read is always outstanding until the
// client closes or the stream stops; the newest unanswered request waits in
// pending_ (an older one there is skipped); one frame computes at a time, its
// answer waits in ready_ while a write is in flight; a new frame is computed
// only when no answer is waiting, so a viewer that does not read costs one
// request, one answer and one write in flight. Deltas are taken at write time
// against the last PVS written, so skipped frames never break them.
#include <chrono>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "rpc/frame_answer.h"
#include "rpc/stream_reactor.h"
#include "rpc/streams.h"
#include "wire/calls.h"
#include "wire/convert.h"

namespace voxvis::server {
namespace {

using Clock = std::chrono::steady_clock;

class ViewReactor final
    : public StreamReactor<v1::ViewRequest, v1::ViewResponse, ViewReactor> {
  friend class StreamReactor<v1::ViewRequest, v1::ViewResponse, ViewReactor>;

 public:
  ViewReactor(Admission& admission, Serving& serving, grpc::CallbackServerContext* ctx)
      : StreamReactor(admission, serving, "View") {
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
      serving_.pool().submit(client_, [this](Scratch& scratch) { compute(*entry_, scratch); });
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
      admission_.count_dropped();
    } else {
      computed_.frame = job_.frame;
      computed_.received = job_.received;
      computed_.skipped = job_skipped_;
      bool sampled = false;
      error = serving_.serve_frame(e, &viewer_, job_.camera, job_.t, scratch, &computed_.result, &sampled);
      served = error.ok();
      if (served && sampled) check.emplace(computed_.result);
    }
    // Once mu_ is released another thread may end and delete this stream
    // (unless `del` says this job is the last): what the check needs after
    // it is copied first, the scene held by `keep`.
    Serving* const serving = &serving_;
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
    if (check) serving->verify_served(*keep, viewer, frame, camera, *check);
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
    serving_.release_viewer(client_, entry_, viewer_);
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

}  // namespace

grpc::ServerBidiReactor<grpc::ByteBuffer, grpc::ByteBuffer>* new_view_stream(
    Admission& admission, Serving& serving, grpc::CallbackServerContext* ctx) {
  return new ViewReactor(admission, serving, ctx);
}

}  // namespace voxvis::server
