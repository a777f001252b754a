// expiry_queue.cpp — the calendar queue of TBV expiries (expiry_queue.h).
//
// Why it is exact: key() is monotone in the expiry (a division by a power of
// two, then floor), so an entry whose key is below the key of t expires
// before t, and one that expires at or before t has a key at or below t's.
// pop_due therefore takes the buckets from the cursor to before t's key
// whole, and from t's own bucket the entries whose own expiry is at or
// before t. And the first bucket from the cursor that holds anything holds
// the least expiry: every later bucket's entries have later keys.
#include "expiry_queue.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <tuple>

namespace voxvis::detail {

namespace {

bool before(const ExpiryEntry& a, const ExpiryEntry& b) {
  return std::tie(a.expiry, a.slot, a.epoch) < std::tie(b.expiry, b.slot, b.epoch);
}

/// The order of the heap beyond the ring: its front is the earliest.
bool after(const ExpiryEntry& a, const ExpiryEntry& b) { return before(b, a); }

}  // namespace

std::int64_t ExpiryQueue::key(double expiry) {
  // Dividing by a power of two is exact; the clamp keeps any finite expiry
  // in range.
  constexpr double kLimit = 0x1p62;
  return static_cast<std::int64_t>(std::floor(std::clamp(expiry / kBucketSeconds, -kLimit, kLimit)));
}

void ExpiryQueue::push(const ExpiryEntry& e, double now) {
  if (ring_.empty()) {
    ring_.resize(kBuckets);
    cursor_ = key(now);
  }
  put(e);
  earliest_ = std::fmin(earliest_, e.expiry);
}

void ExpiryQueue::put(const ExpiryEntry& e) {
  // An entry earlier than the cursor (renewed ahead of a frame that went
  // past it) waits in the cursor's bucket, which is looked in first.
  const std::int64_t k = std::max(key(e.expiry), cursor_);
  if (k - cursor_ < kBuckets) {
    const std::size_t i = index(k);
    if (k == cursor_) cursor_sorted_ = false;
    ring_[i].push_back(e);
    filled_[i / 64] |= std::uint64_t{1} << (i % 64);
    ++ring_size_;
  } else {
    far_.push_back(e);
    std::push_heap(far_.begin(), far_.end(), after);
  }
}

void ExpiryQueue::release(std::size_t i) {
  // Its memory back: a bucket is filled again a ring's turn later.
  std::vector<ExpiryEntry>().swap(ring_[i]);
  filled_[i / 64] &= ~(std::uint64_t{1} << (i % 64));
}

void ExpiryQueue::take_whole(std::int64_t k, std::vector<ExpiryEntry>* out) {
  const std::size_t i = index(k);
  std::vector<ExpiryEntry>& b = ring_[i];
  if (b.empty()) return;
  const std::size_t first = out->size();
  out->insert(out->end(), b.begin(), b.end());
  std::sort(out->begin() + static_cast<std::ptrdiff_t>(first), out->end(), before);
  ring_size_ -= b.size();
  release(i);
}

void ExpiryQueue::take_sorted(double t, std::vector<ExpiryEntry>* out) {
  const std::size_t i = index(cursor_);
  std::vector<ExpiryEntry>& b = ring_[i];
  if (b.empty()) return;
  if (!cursor_sorted_) {
    std::sort(b.begin(), b.end(), [](const ExpiryEntry& x, const ExpiryEntry& y) { return before(y, x); });
    cursor_sorted_ = true;
  }
  while (!b.empty() && b.back().expiry <= t) {
    out->push_back(b.back());
    b.pop_back();
    --ring_size_;
  }
  if (b.empty()) release(i);
}

void ExpiryQueue::take_far(double t, std::vector<ExpiryEntry>* out) {
  // The heap gives them in order of expiry, after every entry of the ring.
  while (!far_.empty() && far_.front().expiry <= t) {
    std::pop_heap(far_.begin(), far_.end(), after);
    out->push_back(far_.back());
    far_.pop_back();
  }
}

void ExpiryQueue::pop_due(double t, std::vector<ExpiryEntry>* out) {
  if (!any_due(t)) return;
  const std::int64_t kt = key(t);
  // Buckets before t's key hold only entries due at t (the cursor's too:
  // its entries pushed with earlier keys expire before its own key): each
  // is taken whole and sorted once. t's own bucket may also hold later
  // entries: it becomes the cursor's, sorted once, and its due entries are
  // taken from its back, frame after frame. Past the ring's span every
  // bucket is due whole. Buckets come in the order of their keys, and the
  // list beyond the ring after them, so `out` is in order of expiry.
  if (kt <= cursor_) {
    take_sorted(t, out);
  } else {
    const std::int64_t last = std::min(kt, cursor_ + (kBuckets - 1));
    for (std::int64_t k = cursor_; k < last && ring_size_ > 0; ++k) take_whole(k, out);
    cursor_ = last;
    cursor_sorted_ = false;
    if (last == kt) {
      take_sorted(t, out);
    } else {
      take_whole(last, out);
      cursor_ = kt;
    }
  }
  take_far(t, out);
  settle();
}

std::size_t ExpiryQueue::first_filled() const {
  // From the cursor's bucket round the ring: the last word is the first
  // again, for the bits before the cursor's.
  const std::size_t start = index(cursor_), words = filled_.size();
  for (std::size_t n = 0; n <= words; ++n) {
    const std::size_t w = (start / 64 + n) % words;
    std::uint64_t bits = filled_[w];
    if (n == 0) bits &= ~std::uint64_t{0} << (start % 64);
    if (bits) return w * 64 + static_cast<std::size_t>(std::countr_zero(bits));
  }
  return kBuckets;
}

void ExpiryQueue::settle() {
  // The cursor came within reach of entries beyond the ring: they join it,
  // the earliest first, so that each moves once.
  while (!far_.empty() && key(far_.front().expiry) - cursor_ < kBuckets) {
    std::pop_heap(far_.begin(), far_.end(), after);
    const ExpiryEntry e = far_.back();
    far_.pop_back();
    put(e);
  }
  if (ring_size_ == 0) {
    earliest_ = far_.empty() ? std::numeric_limits<double>::infinity() : far_.front().expiry;
    return;
  }
  const std::size_t i = first_filled();
  const std::vector<ExpiryEntry>& b = ring_[i];
  if (i == index(cursor_) && cursor_sorted_) {
    earliest_ = b.back().expiry;
    return;
  }
  earliest_ = std::numeric_limits<double>::infinity();
  for (const ExpiryEntry& e : b) earliest_ = std::fmin(earliest_, e.expiry);
}

std::uint64_t ExpiryQueue::bytes() const {
  std::uint64_t n = ring_.capacity() * sizeof(ring_[0]) + far_.capacity() * sizeof(ExpiryEntry);
  for (const std::vector<ExpiryEntry>& b : ring_) n += b.capacity() * sizeof(ExpiryEntry);
  return n;
}

}  // namespace voxvis::detail
