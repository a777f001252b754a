// frame_answer.h — a served frame (Serving::serve_frame) as its call's
// answer: a GetPvsResponse, a ViewResponse or a Tick stream's TickAnswer.
// The PVS, its delta and the wake go out through ids.h (repeated uint32
// fields for GetPvs and View, IdSets for Tick); everything else is the same
// for all three.
#pragma once

#include <vector>

#include "scenes/scene_entry.h"
#include "voxvis/v1/voxvis.pb.h"
#include "wire/convert.h"
#include "wire/ids.h"

namespace voxvis::server {

/// Writes a served frame of scene `e` into its answer `out`: the time it ran
/// at, its PVS in `encoding` — whole, or the ids added and removed since
/// `*last_sent` (PVS_DELTA needs `last_sent`) — its wake (where the message
/// has one) and its stats; then counts it in the scene's metrics with
/// `latency` (seconds from the request to this answer). With `last_sent`,
/// the PVS then trades places with it: the next delta's base (`result.pvs`
/// is left holding the old base). `scratch`: reused
/// working memory for IdSet deltas (Tick); may be null for the others.
template <class Msg>
void answer_frame(const SceneEntry& e, FrameResult& result, v1::PvsEncoding encoding,
                  std::vector<ObjectId>* last_sent, double latency, Msg* out,
                  std::vector<ObjectId>* scratch = nullptr) {
  std::vector<ObjectId>& pvs = result.pvs;
  out->set_t(result.t);
  if constexpr (requires { out->mutable_added(); }) {
    if (encoding == v1::PVS_DELTA) {
      put_difference(pvs, *last_sent, out->mutable_added(), scratch);
      put_difference(*last_sent, pvs, out->mutable_removed(), scratch);
    } else {
      put_ids(pvs, out->mutable_pvs());
    }
  } else {
    put_ids(pvs, out->mutable_pvs());  // Only whole PVSs (GetPvs).
  }
  if constexpr (requires { out->mutable_wake(); }) put_ids(result.wake, out->mutable_wake());
  stats_to_proto(result.stats, out->mutable_stats());
  if (e.metrics) e.metrics->frame(result.stats, latency);
  // The PVS becomes the next delta's base; the frame's result takes the old
  // base's buffer, so that neither allocates next time.
  if (last_sent) last_sent->swap(pvs);
}

}  // namespace voxvis::server
