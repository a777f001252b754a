// get_pvs.cpp — GetPvs (unary_calls.h): one frame for a viewer of one frame,
// checked on the callback thread and served in a pool job.
#include <chrono>
#include <string>

#include "rpc/frame_answer.h"
#include "rpc/unary_calls.h"
#include "wire/convert.h"

namespace voxvis::server {
namespace {

using Clock = std::chrono::steady_clock;
using Call = TypedUnaryCall<v1::GetPvsRequest, v1::GetPvsResponse>;

/// The pool job. Work nobody waits for any more is answered without running.
void serve(UnaryDeps& d, grpc::CallbackServerContext* ctx, Call* r, SceneEntry& e, const Camera& camera, double t,
           Clock::time_point received, Scratch& scratch) {
  if (answered_unrun(d, ctx, r, "GetPvs")) return;
  FrameResult result;
  bool check = false;
  if (grpc::Status g = d.serving.serve_frame(e, nullptr, camera, t, scratch, &result, &check); !g.ok()) {
    d.admission.finish_unary(r, "GetPvs", g);
    return;
  }
  const double latency = std::chrono::duration<double>(Clock::now() - received).count();
  answer_frame(e, result, v1::PVS_FULL, nullptr, latency, &r->resp);
  const std::string peer = check ? ctx->peer() : std::string();
  d.admission.finish_unary(r, "GetPvs", grpc::Status::OK);
  if (check) d.serving.verify_served(e, peer + " (GetPvs)", 0, camera, result);
}

}  // namespace

grpc::ServerUnaryReactor* get_pvs(UnaryDeps& d, grpc::CallbackServerContext* ctx, const Raw* in, Raw* out) {
  grpc::ServerUnaryReactor* reactor = nullptr;
  Call* r = d.admission.start_unary<v1::GetPvsRequest, v1::GetPvsResponse>("GetPvs", ctx, Role::Viewer, in, out,
                                                                           &reactor);
  if (!r) return reactor;
  std::shared_ptr<SceneEntry> e = find_or_finish(d, r, "GetPvs", r->req.scene_id());
  if (!e) return reactor;
  Camera camera;
  if (Status s = camera_from_proto(r->req.camera(), r->req.has_camera(), &camera); !s) {
    d.admission.finish_unary(r, "GetPvs", invalid(s));
    return reactor;
  }
  if (Status s = validate_time("t", r->req.t()); !s) {
    d.admission.finish_unary(r, "GetPvs", invalid(s));
    return reactor;
  }
  const Clock::time_point received = Clock::now();
  d.serving.pool().submit(ctx->peer(), [&d, ctx, r, e, camera, t = r->req.t(), received](Scratch& scratch) {
    serve(d, ctx, r, *e, camera, t, received, scratch);
  });
  return reactor;
}

}  // namespace voxvis::server
