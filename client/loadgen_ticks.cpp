// loadgen_ticks.cpp — `voxvis loadgen --tick`'s driver: one Tick stream whose
// every request carries all N viewers' cameras, as a game server sends its
// whole tick. Tick k is due at start + k / rate; latency is a tick's, from
// its request written to its response read.
#include "loadgen.h"

namespace voxvis::cli::loadgen {
namespace {

class TickStream final : public PacedStream<v1::TickRequest, v1::TickResponse> {
 public:
  explicit TickStream(Shared* shared) : PacedStream("tick stream", shared) {}

  void start(const client::Client& client, const std::string& scene_id, v1::PvsEncoding encoding, int viewers) {
    scene_id_ = scene_id;
    encoding_ = encoding;
    viewers_ = viewers;
    begin(client, [&](grpc::ClientContext* context, auto* self) { client.stub().async()->Tick(context, self); });
  }

  /// Sends tick `tick` at time `t`, viewer v's camera `camera(v)`, unless a
  /// write is outstanding. The request's viewer list is built once and its
  /// cameras overwritten in place.
  template <class CameraOf>
  bool send_tick(std::uint64_t tick, double t, CameraOf&& camera) {
    const bool sent = send(tick, [&](v1::TickRequest& request, bool first) {
      if (first) {
        request.set_scene_id(scene_id_);
        request.set_encoding(encoding_);
        for (int v = 0; v < viewers_; ++v) request.add_viewers()->set_viewer(static_cast<std::uint64_t>(v));
      } else {
        request.clear_scene_id();
        request.clear_encoding();
      }
      request.set_tick(tick);
      request.set_t(t);
      for (int v = 0; v < viewers_; ++v) client::to_proto(camera(v), request.mutable_viewers(v)->mutable_camera());
    });
    if (sent) shared_->ticks_sent.fetch_add(1, std::memory_order_relaxed);
    return sent;
  }

 private:
  std::uint64_t on_answer(const v1::TickResponse& response) override {
    std::uint64_t answered = 0, failed = 0;
    for (const v1::TickAnswer& a : response.answers()) {
      if (a.has_error()) {
        ++failed;
        std::lock_guard<std::mutex> lock(shared_->mu);
        if (shared_->first_error.empty()) {
          shared_->first_error = "tick " + std::to_string(response.tick()) + ", viewer " +
                                 std::to_string(a.viewer()) + ": " + a.error().field() + ": " +
                                 a.error().description();
        }
      } else {
        ++answered;
      }
    }
    shared_->frames.fetch_add(answered, std::memory_order_relaxed);
    shared_->answer_errors.fetch_add(failed, std::memory_order_relaxed);
    shared_->ticks_answered.fetch_add(1, std::memory_order_relaxed);
    shared_->server_skipped.fetch_add(response.ticks_skipped(), std::memory_order_relaxed);
    return response.tick();
  }

  std::string scene_id_;
  v1::PvsEncoding encoding_ = v1::PVS_FULL;
  int viewers_ = 0;
};

}  // namespace

bool drive_ticks(const LoadgenArgs& args, const CameraSource& source, const client::Client& client,
                 Shared& shared) {
  std::vector<std::unique_ptr<TickStream>> streams;
  streams.push_back(std::make_unique<TickStream>(&shared));
  TickStream& stream = *streams.front();
  stream.start(client, args.scene, args.delta ? v1::PVS_DELTA : v1::PVS_FULL, args.viewers);

  ProgressLine progress(args, shared);
  pace(args, shared, progress, args.rate, [&](std::uint64_t tick, double t) {
    return stream.send_tick(tick, t, [&](int v) { return source.at(v, tick, t); });
  });

  const bool ended = end_streams(streams, shared);
  progress.finish();
  if (!ended) (void)streams.front().release();  // Never freed under a live stream.
  return ended;
}

}  // namespace voxvis::cli::loadgen
