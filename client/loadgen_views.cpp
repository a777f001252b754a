// loadgen_views.cpp — `voxvis loadgen`'s View driver: one View stream per
// viewer, the viewers spread evenly over each frame period so that the
// server sees a steady load rather than N requests at once.
#include "loadgen.h"

namespace voxvis::cli::loadgen {
namespace {

/// One viewer: a View stream driven by the pacing thread.
class Viewer final : public PacedStream<v1::ViewRequest, v1::ViewResponse> {
 public:
  Viewer(int index, Shared* shared) : PacedStream("viewer " + std::to_string(index), shared) {}

  void start(const client::Client& client, const std::string& scene_id, v1::PvsEncoding encoding) {
    scene_id_ = scene_id;
    encoding_ = encoding;
    begin(client, [&](grpc::ClientContext* context, auto* self) { client.stub().async()->View(context, self); });
  }

  /// Sends frame `frame` at time `t` unless a write is outstanding.
  bool send_frame(std::uint64_t frame, double t, const Camera& camera) {
    return send(frame, [&](v1::ViewRequest& request, bool first) {
      if (first) {
        request.set_scene_id(scene_id_);
        request.set_encoding(encoding_);
      } else {
        request.clear_scene_id();
        request.clear_encoding();
      }
      request.set_frame(frame);
      request.set_t(t);
      client::to_proto(camera, request.mutable_camera());
    });
  }

 private:
  std::uint64_t on_answer(const v1::ViewResponse& response) override {
    shared_->frames.fetch_add(1, std::memory_order_relaxed);
    shared_->server_skipped.fetch_add(response.frames_skipped(), std::memory_order_relaxed);
    return response.frame();
  }

  std::string scene_id_;
  v1::PvsEncoding encoding_ = v1::PVS_FULL;
};

}  // namespace

bool drive_views(const LoadgenArgs& args, const CameraSource& source,
                 const std::vector<std::unique_ptr<client::Client>>& clients, Shared& shared) {
  const v1::PvsEncoding encoding = args.delta ? v1::PVS_DELTA : v1::PVS_FULL;
  std::vector<std::unique_ptr<Viewer>> viewers;
  viewers.reserve(static_cast<std::size_t>(args.viewers));
  for (int v = 0; v < args.viewers; ++v) {
    viewers.push_back(std::make_unique<Viewer>(v, &shared));
    viewers.back()->start(*clients[static_cast<std::size_t>(v) % clients.size()], args.scene, encoding);
  }

  // Viewer v's frame f is message f * N + v: due at start + (f + v / N) /
  // rate, the viewers spread evenly over each period.
  ProgressLine progress(args, shared);
  const auto n = static_cast<std::uint64_t>(args.viewers);
  pace(args, shared, progress, args.rate * static_cast<double>(n), [&](std::uint64_t k, double t) {
    const auto v = static_cast<int>(k % n);
    const std::uint64_t frame = k / n;
    return viewers[static_cast<std::size_t>(v)]->send_frame(frame, t, source.at(v, frame, t));
  });

  const bool ended = end_streams(viewers, shared);
  progress.finish();
  if (!ended) {
    // Reactors must outlive OnDone; never free them under a live stream.
    for (auto& v : viewers) (void)v.release();
  }
  return ended;
}

}  // namespace voxvis::cli::loadgen
