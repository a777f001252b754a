// ids.h — object ids onto the wire, in one place: PVSs, their deltas, wake
// lists and too-fast lists go out through these, as repeated uint32 fields
// (GetPvs, View, Simulate, Tick's too_fast) or as IdSets (Tick's answers).
// Every id list the server keeps is ascending; so is every one it writes.
#pragma once

#include <cstdint>
#include <vector>

#include <google/protobuf/repeated_field.h>

#include "voxvis/types.h"
#include "voxvis/v1/voxvis.pb.h"

namespace voxvis::server {

using Ids = std::vector<ObjectId>;
using RepeatedIds = google::protobuf::RepeatedField<std::uint32_t>;

/// `ids`, appended.
void put_ids(const Ids& ids, RepeatedIds* out);
/// `ids` (ascending) as the smaller of IdSet's two forms (gaps or bitset),
/// replacing what `out` held.
void put_ids(const Ids& ids, v1::IdSet* out);

/// a \ b (both ascending), appended; `scratch` is not used.
void put_difference(const Ids& a, const Ids& b, RepeatedIds* out, Ids* scratch = nullptr);
/// a \ b (both ascending) as an IdSet, made in `scratch` (reused working memory).
void put_difference(const Ids& a, const Ids& b, v1::IdSet* out, Ids* scratch);

/// A wake list at `version` holding `now`, for a stream that last sent
/// `sent` (null: nothing yet): the whole list the first time, else the ids
/// that joined and left.
void put_wake(std::uint64_t version, const Ids& now, const Ids* sent, v1::WakeList* out);

}  // namespace voxvis::server
