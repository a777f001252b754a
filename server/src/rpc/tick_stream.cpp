// tick_stream.cpp — the Tick stream: a game server's whole tick (moves and
// every viewer's camera) in one message, every viewer answered in one.
//
// State machine (all under mu_, as View's in view_stream.cpp): a read is always
// outstanding until the client closes or the stream stops. A request's moves
// go to the scene's strand at once, in order (never skipped); its viewers
// wait in pending_, where a newer request replaces them (latest tick wins;
// the `left` ids of the replaced one are kept). One tick computes at a time:
// it starts when no answer is waiting, after the moves sent before it (a
// job on the strand starts it when moves are in flight), and fans out one
// pool job a viewer, so the viewers of a tick run in parallel; the last job
// to end makes the answer. Deltas are taken at write time against each
// viewer's last PVS written, so skipped ticks never break them.
//
// Viewer states (the engine's viewer, the last PVS written) live in viewers_:
// changed under mu_ between ticks only (when a tick starts, and when its
// answer is written), and read by a tick's jobs, one job a viewer, while no
// other thread changes them.
#include "rpc/streams.h"

#include <algorithm>
#include <chrono>
#include <memory>
#include <mutex>
#include <optional>
#include <unordered_map>
#include <utility>
#include <vector>

#include "rpc/frame_answer.h"
#include "rpc/stream_reactor.h"
#include "wire/ids.h"

namespace voxvis::server {
namespace {

using Clock = std::chrono::steady_clock;

/// Viewers one Tick stream keeps at most, and answers in one tick.
constexpr std::size_t kMaxTickViewers = 1024;
/// Move batches a stream may have waiting to be applied; beyond, it reads no
/// further request until one is applied (the client's writes then wait), so
/// a client sending moves faster than they apply costs bounded memory.
constexpr std::size_t kMaxMoveBatches = 4;

class TickReactor final : public StreamReactor<v1::TickRequest, v1::TickResponse, TickReactor> {
  friend class StreamReactor<v1::TickRequest, v1::TickResponse, TickReactor>;

 public:
  TickReactor(Admission& admission, Serving& serving, grpc::CallbackServerContext* ctx)
      : StreamReactor(admission, serving, "Tick") {
    const grpc::Status admitted = admit(ctx, Role::Viewer);
    may_move_ = admitted.ok() && admission.authorize(ctx, Role::Simulation).ok();
    std::lock_guard<std::mutex> lock(mu_);
    open_locked(admitted);
  }

 private:
  struct ViewerState {
    FrameViewer engine;               // The engine's viewer, added by its first frame.
    std::vector<ObjectId> last_sent;  // PVS of the last answer written.
  };
  /// One viewer entry of a tick: its camera, or why it was refused.
  struct Entry {
    std::uint64_t viewer = 0;
    Camera camera;
    Status error;  // Not OK: refused, field named from the request.
    ViewerState* state = nullptr;  // Set when the tick starts.
    FrameResult result;            // Filled by the viewer's job.
  };
  struct Pending {
    std::uint64_t tick = 0;
    double t = 0.0;
    std::vector<Entry> entries;
    Clock::time_point received;
  };
  struct Ready {
    Pending tick;
    std::uint32_t skipped = 0;
  };

  void on_read_locked(bool ok, const grpc::Status& parsed) {
    if (!ok) {
      eof_ = true;
    } else if (!stopping_) {
      const grpc::Status s = parsed.ok() ? accept_locked() : parsed;
      if (!s.ok()) {
        stop_locked(s);
      } else if (batches_waiting_locked() < kMaxMoveBatches) {
        start_read();
      } else {
        read_paused_ = true;
      }
    }
    advance_locked();
  }

  std::size_t batches_waiting_locked() const { return static_cast<std::size_t>(moves_in_flight_) + held_moves_.size(); }

  /// Reads on when reading waited for move batches to apply.
  void resume_read_locked() {
    if (!read_paused_ || stopping_ || batches_waiting_locked() >= kMaxMoveBatches) return;
    read_paused_ = false;
    start_read();
  }

  grpc::Status accept_locked() {
    const v1::TickRequest& r = read_.get();
    bool first = false;
    if (grpc::Status s = accept_sequence_locked(r.scene_id(), r.encoding(), &first, "tick", r.tick(), r.t()); !s.ok())
      return s;
    if (first) subscribe_wake_locked();
    if (static_cast<std::size_t>(r.viewers_size()) > kMaxTickViewers)
      return invalid(Status::Error("viewers", "at most " + std::to_string(kMaxTickViewers) + " a tick, got " +
                                                  std::to_string(r.viewers_size())));
    if (r.left_size() > static_cast<int>(kMaxTickViewers))
      return invalid(Status::Error("left", "at most " + std::to_string(kMaxTickViewers) + " a tick, got " +
                                               std::to_string(r.left_size())));
    std::vector<Move> moves;
    if (r.moves_size() > 0) {
      if (!may_move_)
        return grpc::Status(grpc::StatusCode::PERMISSION_DENIED,
                            "moves: a tick that carries moves needs the simulation role");
      if (Status s = moves_from_proto(r.moves(), "moves", &moves); !s) return invalid(s);
    }
    Pending p;
    p.tick = r.tick();
    p.t = r.t();
    p.received = Clock::now();
    // Entries (and their frames' buffers) come back from earlier ticks.
    if (!spare_entries_.empty()) {
      p.entries = std::move(spare_entries_.back());
      spare_entries_.pop_back();
    }
    p.entries.resize(static_cast<std::size_t>(r.viewers_size()));
    for (int i = 0; i < r.viewers_size(); ++i) {
      const v1::TickViewer& v = r.viewers(i);
      Entry& e = p.entries[static_cast<std::size_t>(i)];
      e.viewer = v.viewer();
      e.state = nullptr;
      e.error = Status::Ok();
      if (Status s = camera_from_proto(v.camera(), v.has_camera(), &e.camera); !s)
        e.error = Status::Error("viewers[" + std::to_string(i) + "]." + s.field, s.message);
    }
    // A viewer given twice: the later entries fail, naming the first.
    ids_.clear();
    for (int i = 0; i < r.viewers_size(); ++i) ids_.emplace_back(r.viewers(i).viewer(), i);
    std::sort(ids_.begin(), ids_.end());
    for (std::size_t k = 1; k < ids_.size(); ++k) {
      if (ids_[k].first != ids_[k - 1].first) continue;
      std::size_t head = k - 1;
      while (head > 0 && ids_[head - 1].first == ids_[k].first) --head;
      const int i = ids_[k].second;
      p.entries[static_cast<std::size_t>(i)].error =
          Status::Error("viewers[" + std::to_string(i) + "].viewer",
                        "viewer " + std::to_string(ids_[k].first) + " is given twice in one tick (first at viewers[" +
                            std::to_string(ids_[head].second) + "])");
    }
    sequence_taken_locked(r.tick(), r.t());
    for (std::uint64_t id : r.left()) left_.push_back(id);
    if (!moves.empty()) {
      // While a tick computes, later moves wait for its frames: a tick's
      // answers see exactly the moves sent up to it.
      if (computing_) {
        held_moves_.emplace_back(r.t(), std::move(moves));
      } else {
        post_moves_locked(r.t(), std::move(moves));
      }
    }
    if (pending_) {
      ++skipped_;
      recycle_locked(std::move(pending_->entries));
    }
    pending_ = std::move(p);
    return grpc::Status::OK;
  }

  /// The scene's wake list comes to sink_ from a job of the scene's strand,
  /// ahead of the first tick's moves; the first tick waits for it as for
  /// moves, so that its answer carries the whole list.
  void subscribe_wake_locked() {
    ++moves_in_flight_;
    ++jobs_;
    entry_->strand->post([this, entry = entry_, sink = sink_](Scratch&) {
      if (!entry->deleted.load()) entry->subscribe(sink);
      bool del;
      {
        std::lock_guard<std::mutex> lock(mu_);
        --moves_in_flight_;
        resume_read_locked();
        advance_locked();
        del = end_job_locked();
      }
      if (del) release();
    });
  }

  /// The moves go to the scene's strand now, in order: a replaced tick's
  /// moves are applied all the same.
  void post_moves_locked(double t, std::vector<Move> moves) {
    ++moves_in_flight_;
    ++jobs_;
    entry_->strand->post([this, entry = entry_, t, moves = std::move(moves)](Scratch&) {
      MoveReport report;
      grpc::Status status;
      bool stopped;
      {
        std::lock_guard<std::mutex> lock(mu_);
        stopped = stopping_;
      }
      if (stopped) {
        admission_.count_dropped();
      } else if (entry->deleted.load()) {
        status = deleted(entry->id);
      } else {
        status = serving_.apply_batch(*entry, t, moves, "", &report);
      }
      bool del;
      {
        std::lock_guard<std::mutex> lock(mu_);
        --moves_in_flight_;
        resume_read_locked();
        if (!status.ok()) {
          stop_locked(status);
        } else {
          moves_applied_ += report.applied;
          too_fast_.insert(too_fast_.end(), report.too_fast.begin(), report.too_fast.end());
        }
        advance_locked();
        del = end_job_locked();
      }
      if (del) release();
    });
  }

  void on_stop_locked() {
    pending_.reset();
    held_moves_.clear();  // Nobody will read their acknowledgement.
  }
  void on_done() {}

  void advance_locked() {
    if (finished_) return;
    if (!writing_ && ready_) write_locked();
    if (!stopping_ && !computing_ && pending_ && !ready_ && moves_in_flight_ == 0) start_tick_locked();
    const bool idle = !writing_ && !computing_ && !ready_ && moves_in_flight_ == 0;
    if (idle && (stopping_ || (eof_ && !pending_))) finish_locked();
  }

  /// Takes the pending tick up: drops the viewers that left, finds or makes
  /// each entry's viewer state, and hands one job a viewer to the pool.
  void start_tick_locked() {
    computing_ = true;
    tick_ = std::move(*pending_);
    pending_.reset();
    tick_skipped_ = skipped_;
    skipped_ = 0;
    for (std::uint64_t id : left_) {
      auto it = viewers_.find(id);
      if (it == viewers_.end()) continue;
      serving_.release_viewer(client_, entry_, it->second.engine);
      viewers_.erase(it);
      count_viewers_locked(-1);
    }
    left_.clear();
    std::vector<std::size_t>& run = run_;
    run.clear();
    for (std::size_t i = 0; i < tick_.entries.size(); ++i) {
      Entry& e = tick_.entries[i];
      if (!e.error) continue;
      auto it = viewers_.find(e.viewer);
      if (it == viewers_.end()) {
        if (viewers_.size() >= kMaxTickViewers) {
          e.error = Status::Error("viewers[" + std::to_string(i) + "].viewer",
                                  "this stream already keeps " + std::to_string(kMaxTickViewers) +
                                      " viewers; name the ones that are gone in `left`");
          continue;
        }
        it = viewers_.emplace(e.viewer, ViewerState{}).first;
        count_viewers_locked(+1);
      }
      e.state = &it->second;
      run.push_back(i);
    }
    outstanding_ = run.size();
    if (run.empty()) {
      finish_tick_locked();
      return;
    }
    // [this, i] fits the job's own storage: no allocation a viewer. The
    // stream outlives its jobs (jobs_), and entry_ is fixed by now.
    for (std::size_t i : run) {
      ++jobs_;
      serving_.pool().submit(client_, [this, i](Scratch& scratch) { compute(*entry_, i, scratch); });
    }
  }

  /// The scene's count of viewers, and its metrics', follow the viewers kept.
  void count_viewers_locked(int delta) {
    entry_->viewers.fetch_add(static_cast<std::uint32_t>(delta), std::memory_order_relaxed);
    if (entry_->metrics) entry_->metrics->viewers(delta);
  }

  // Pool job: the frame of entry i of the tick being computed.
  void compute(SceneEntry& e, std::size_t i, Scratch& scratch) {
    bool stopped;
    {
      std::lock_guard<std::mutex> lock(mu_);
      stopped = stopping_;
    }
    Entry& entry = tick_.entries[i];  // Only this job touches it until it ends.
    grpc::Status error;
    std::optional<FrameResult> check;  // Verify mode: a copy of the frame served.
    if (stopped) {
      admission_.count_dropped();
    } else {
      bool sample = false;
      error = serving_.serve_frame(e, &entry.state->engine, entry.camera, tick_.t, scratch, &entry.result, &sample);
      if (error.ok() && sample) check.emplace(entry.result);
    }
    // As View's: what the check needs is copied before mu_ is released, after
    // which the tick may be written and the stream deleted (with its hold on
    // the scene: `keep` holds it for the check).
    Serving* const serving = &serving_;
    const std::shared_ptr<SceneEntry> keep = check ? entry_ : nullptr;
    const std::uint64_t tick = tick_.tick;
    const Camera camera = entry.camera;
    const std::string viewer = check ? client_ + " tick viewer " + std::to_string(entry.viewer) : std::string();
    bool del;
    {
      std::lock_guard<std::mutex> lock(mu_);
      if (!error.ok()) stop_locked(error);
      if (--outstanding_ == 0) finish_tick_locked();
      del = end_job_locked();
    }
    if (check) serving->verify_served(*keep, viewer, tick, camera, *check);
    if (del) release();
  }

  void finish_tick_locked() {
    computing_ = false;
    for (auto& [t, moves] : held_moves_) post_moves_locked(t, std::move(moves));
    held_moves_.clear();
    if (!stopping_) ready_.emplace(Ready{std::move(tick_), tick_skipped_});
    tick_ = Pending{};
    advance_locked();
  }

  void write_locked() {
    Ready& r = *ready_;
    auto& w = write_.fresh();
    w.set_tick(r.tick.tick);
    w.set_encoding(encoding_);
    w.set_ticks_skipped(r.skipped);
    const double latency = std::chrono::duration<double>(Clock::now() - r.tick.received).count();
    for (Entry& e : r.tick.entries) {
      v1::TickAnswer* a = w.add_answers();
      a->set_viewer(e.viewer);
      if (!e.error) {
        a->mutable_error()->set_field(e.error.field);
        a->mutable_error()->set_description(e.error.message);
        continue;
      }
      answer_frame(*entry_, e.result, encoding_, &e.state->last_sent, latency, a, &scratch_);
    }
    if (entry_->metrics && r.skipped) entry_->metrics->skipped(r.skipped);
    w.set_moves_applied(moves_applied_);
    moves_applied_ = 0;
    std::sort(too_fast_.begin(), too_fast_.end());
    too_fast_.erase(std::unique(too_fast_.begin(), too_fast_.end()), too_fast_.end());
    put_ids(too_fast_, w.mutable_too_fast());
    too_fast_.clear();
    write_wake_locked();
    w.set_server_us(latency * 1e6);
    recycle_locked(std::move(r.tick.entries));
    ready_.reset();
    start_write_locked();
  }

  /// The scene's wake list, when it changed since the last one written.
  void write_wake_locked() {
    std::shared_ptr<const WakeSnapshot> now = sink_->latest();
    if (!now || now == wake_sent_ || (wake_sent_ && now->ids == wake_sent_->ids)) return;
    put_wake(now->version, now->ids, wake_sent_ ? &wake_sent_->ids : nullptr, write_.get().mutable_wake());
    wake_sent_ = std::move(now);
  }

  /// Keeps a tick's entries for a later tick (two lists at most: the one
  /// computing and the one pending are the others alive).
  void recycle_locked(std::vector<Entry>&& entries) {
    if (spare_entries_.size() < 2) spare_entries_.push_back(std::move(entries));
  }

  void on_release() {
    if (!entry_) return;
    entry_->unsubscribe(sink_);
    for (auto& [id, v] : viewers_) {
      serving_.release_viewer(client_, entry_, v.engine);
      count_viewers_locked(-1);
    }
  }

  bool may_move_ = false;  // The token's role allows moves.
  std::optional<Pending> pending_;  // Guarded by mu_.
  std::vector<std::uint64_t> left_;  // Guarded by mu_: ids to drop when the next tick starts.
  std::uint32_t skipped_ = 0;       // Guarded by mu_.
  int moves_in_flight_ = 0;         // Guarded by mu_: jobs posted to the strand (batches, the subscription), not yet run.
  std::uint32_t moves_applied_ = 0;  // Guarded by mu_: since the last answer written.
  std::vector<ObjectId> too_fast_;   // Guarded by mu_: the same.
  std::vector<std::pair<double, std::vector<Move>>> held_moves_;  // Guarded by mu_: sent while a tick computed.
  bool computing_ = false, eof_ = false;  // Guarded by mu_.
  bool read_paused_ = false;              // Guarded by mu_: no read outstanding until batches apply.
  Pending tick_;                    // The tick computing: entries touched by their own jobs.
  std::uint32_t tick_skipped_ = 0;  // Guarded by mu_.
  std::size_t outstanding_ = 0;     // Guarded by mu_: jobs of tick_ not ended.
  std::optional<Ready> ready_;      // Guarded by mu_.
  std::unordered_map<std::uint64_t, ViewerState> viewers_;  // See the top of this file.
  std::vector<ObjectId> scratch_;   // Guarded by mu_: write_locked's working memory.
  std::vector<std::pair<std::uint64_t, int>> ids_;  // Guarded by mu_: accept_locked's.
  std::vector<std::size_t> run_;    // Guarded by mu_: start_tick_locked's.
  std::vector<std::vector<Entry>> spare_entries_;  // Guarded by mu_: see recycle_locked.
  std::shared_ptr<StreamWakeSink> sink_ = std::make_shared<StreamWakeSink>();  // The scene's wake list.
  std::shared_ptr<const WakeSnapshot> wake_sent_;  // Guarded by mu_.
};

}  // namespace

grpc::ServerBidiReactor<grpc::ByteBuffer, grpc::ByteBuffer>* new_tick_stream(Admission& admission, Serving& serving,
                                                                             grpc::CallbackServerContext* ctx) {
  return new TickReactor(admission, serving, ctx);
}

}  // namespace voxvis::server
