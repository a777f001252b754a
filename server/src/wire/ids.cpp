#include "wire/ids.h"

#include <algorithm>
#include <iterator>
#include <string>
#include <utility>

namespace voxvis::server {

void put_ids(const Ids& ids, RepeatedIds* out) {
  out->Reserve(out->size() + static_cast<int>(ids.size()));
  for (ObjectId id : ids) out->AddAlreadyReserved(id);
}

void put_ids(const Ids& ids, v1::IdSet* out) {
  out->Clear();
  if (ids.empty()) return;
  // Bytes of each form: a varint a gap, against one bit an id of the range.
  std::size_t gap_bytes = 0;
  ObjectId prev = 0;
  for (ObjectId id : ids) {
    const std::uint32_t gap = id - prev;
    gap_bytes += gap < (1u << 7) ? 1 : gap < (1u << 14) ? 2 : gap < (1u << 21) ? 3 : gap < (1u << 28) ? 4 : 5;
    prev = id;
  }
  const std::uint64_t span = std::uint64_t{ids.back()} - ids.front() + 1;
  const std::uint64_t bit_bytes = (span + 7) / 8 + 5;  // The bits and the base.
  if (bit_bytes < gap_bytes) {
    std::string bits(static_cast<std::size_t>((span + 7) / 8), '\0');
    for (ObjectId id : ids) {
      const std::uint64_t k = id - ids.front();
      bits[static_cast<std::size_t>(k / 8)] = static_cast<char>(bits[static_cast<std::size_t>(k / 8)] | (1 << (k % 8)));
    }
    out->set_base(ids.front());
    out->set_bits(std::move(bits));
    return;
  }
  auto* gaps = out->mutable_gaps();
  gaps->Reserve(static_cast<int>(ids.size()));
  prev = 0;
  for (ObjectId id : ids) {
    gaps->AddAlreadyReserved(id - prev);
    prev = id;
  }
}

void put_difference(const Ids& a, const Ids& b, RepeatedIds* out, Ids*) {
  std::size_t j = 0;
  for (ObjectId id : a) {
    while (j < b.size() && b[j] < id) ++j;
    if (j == b.size() || b[j] != id) out->Add(id);
  }
}

void put_difference(const Ids& a, const Ids& b, v1::IdSet* out, Ids* scratch) {
  scratch->clear();
  std::set_difference(a.begin(), a.end(), b.begin(), b.end(), std::back_inserter(*scratch));
  put_ids(*scratch, out);
}

void put_wake(std::uint64_t version, const Ids& now, const Ids* sent, v1::WakeList* out) {
  out->set_version(version);
  out->set_size(static_cast<std::uint32_t>(now.size()));
  if (sent == nullptr) {
    out->set_full(true);
    put_ids(now, out->mutable_ids());
  } else {
    put_difference(now, *sent, out->mutable_woken());
    put_difference(*sent, now, out->mutable_slept());
  }
}

}  // namespace voxvis::server
