// tick_session.cpp — TickSession (voxvis/client.h): the Tick stream,
// lock-step, with each viewer's PVS and the scene's wake list reassembled.
#include <string>
#include <utility>
#include <vector>

#include "voxvis/client.h"

namespace voxvis::client {

void TickSession::open(const std::string& scene_id, v1::PvsEncoding encoding) {
  start(&v1::Visibility::Stub::Tick, scene_id, encoding);
  pvs_.clear();
  wake_ = WakeTracker{};
}

bool TickSession::tick(std::uint64_t tick_no, double t, const std::vector<Move>& moves,
                       const std::vector<TickCamera>& viewers, const std::vector<std::uint64_t>& left,
                       TickAnswer* out) {
  v1::TickRequest request;
  if (!ready(&request)) return false;
  request.set_tick(tick_no);
  request.set_t(t);
  for (const Move& m : moves) to_proto(m, request.add_moves());
  for (const TickCamera& v : viewers) {
    v1::TickViewer* p = request.add_viewers();
    p->set_viewer(v.viewer);
    to_proto(v.camera, p->mutable_camera());
  }
  for (std::uint64_t id : left) request.add_left(id);
  if (!stream_->Write(request)) return false;
  v1::TickResponse response;
  if (!stream_->Read(&response)) return false;
  const std::string where = "tick " + std::to_string(tick_no);
  if (response.tick() != tick_no)
    return fail("protocol: asked for " + where + ", got an answer to tick " + std::to_string(response.tick()));
  if (response.encoding() != encoding_)
    return fail(std::string("protocol: asked for ") + v1::PvsEncoding_Name(encoding_) + ", got " +
                v1::PvsEncoding_Name(response.encoding()));
  if (response.answers_size() != static_cast<int>(viewers.size()))
    return fail("protocol: " + where + ": " + std::to_string(viewers.size()) + " viewers asked, " +
                std::to_string(response.answers_size()) + " answered");
  // The viewers that left are gone on the server before the frames.
  for (std::uint64_t id : left) pvs_.erase(id);
  out->tick = tick_no;
  out->viewers.resize(viewers.size());
  std::string why;
  for (int i = 0; i < response.answers_size(); ++i) {
    const v1::TickAnswer& a = response.answers(i);
    TickViewerAnswer& v = out->viewers[static_cast<std::size_t>(i)];
    const std::string at = where + ": answers[" + std::to_string(i) + "]";
    if (a.viewer() != viewers[static_cast<std::size_t>(i)].viewer)
      return fail("protocol: " + at + " is for viewer " + std::to_string(a.viewer()) + ", asked for " +
                  std::to_string(viewers[static_cast<std::size_t>(i)].viewer));
    v.viewer = a.viewer();
    v.error_field.clear();
    v.error.clear();
    v.result = FrameResult{};
    if (a.has_error()) {
      v.error_field = a.error().field();
      v.error = a.error().description();
      continue;
    }
    v.t = a.t();
    if (encoding_ == v1::PVS_DELTA) {
      if (!ids_from_proto(a.added(), &added_, &why)) return fail("protocol: " + at + ".added: " + why);
      if (!ids_from_proto(a.removed(), &removed_, &why)) return fail("protocol: " + at + ".removed: " + why);
      std::vector<ObjectId>& pvs = pvs_[v.viewer];
      if (!apply_delta(&pvs, removed_, added_, &scratch_, &why))
        return fail("protocol: " + at + ": PVS delta does not apply: " + why);
      v.result.pvs = pvs;
    } else if (!ids_from_proto(a.pvs(), &v.result.pvs, &why)) {
      return fail("protocol: " + at + ".pvs: " + why);
    }
    if (!ids_from_proto(a.wake(), &v.result.wake, &why)) return fail("protocol: " + at + ".wake: " + why);
    v.result.t = a.t();
    v.result.stats = from_proto(a.stats());
  }
  out->wake_changed = response.has_wake();
  if (response.has_wake() && !wake_.apply(response.wake(), &why)) return fail("protocol: " + where + ": " + why);
  out->ticks_skipped = response.ticks_skipped();
  out->moves_applied = response.moves_applied();
  out->too_fast.assign(response.too_fast().begin(), response.too_fast().end());
  out->server_us = response.server_us();
  return true;
}

}  // namespace voxvis::client
