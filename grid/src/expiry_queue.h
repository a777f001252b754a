// expiry_queue.h — the TBVs' expiry times as a calendar queue: a ring of
// buckets, each a slice of scene time kBucketSeconds wide, and a heap of the
// entries beyond the ring's span. A frame takes every entry due at its time
// from the few buckets its time reached, in passes over memory laid out in
// order of expiry; a binary heap of 100,000 hidden movers' entries paid a
// dozen cache misses to pop each one (docs/design.md, *Where TBVs are
// stored*). Entries are compared by their own expiry wherever a bucket's
// bounds could tell wrong, so rounding can neither hold back an entry that
// is due nor give one early.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

namespace voxvis::detail {

struct ExpiryEntry {
  double expiry;
  std::uint32_t slot;
  std::uint32_t epoch;  ///< The object's tbv_epoch when pushed.
};

class ExpiryQueue {
 public:
  /// Scene seconds a bucket spans, and the ring's buckets (a power of two):
  /// 128 s in all, beyond the longest default period (60 s, scaled by up to
  /// 1.5). Later entries wait in a heap, joining the ring as it comes
  /// within reach. A bucket emptied gives its memory back, so the queue
  /// holds the ring (48 KiB) and about its entries.
  static constexpr double kBucketSeconds = 1.0 / 16.0;
  static constexpr int kBuckets = 2048;

  /// Adds an entry made at scene time `now`; its expiry must be finite and
  /// `now` no earlier than the time of any pop before.
  void push(const ExpiryEntry& e, double now);
  /// Whether some entry expires at or before t.
  bool any_due(double t) const { return earliest_ <= t; }
  /// Moves every entry expiring at or before t to the end of `out`, in
  /// order of expiry (ties by slot, then epoch).
  void pop_due(double t, std::vector<ExpiryEntry>* out);
  std::size_t size() const { return ring_size_ + far_.size(); }
  bool empty() const { return size() == 0; }
  /// The heap memory it holds, bytes.
  std::uint64_t bytes() const;

 private:
  static std::int64_t key(double expiry);
  static std::size_t index(std::int64_t k) {
    return static_cast<std::size_t>(static_cast<std::uint64_t>(k) & (kBuckets - 1));
  }
  void put(const ExpiryEntry& e);
  void take_whole(std::int64_t k, std::vector<ExpiryEntry>* out);
  void take_sorted(double t, std::vector<ExpiryEntry>* out);
  void take_far(double t, std::vector<ExpiryEntry>* out);
  void release(std::size_t i);
  std::size_t first_filled() const;
  void settle();

  /// Bucket index(k) holds the entries of key k, for k in
  /// [cursor_, cursor_ + kBuckets); the cursor's bucket also those pushed
  /// with an earlier key than the cursor's. Allocated at the first push.
  std::vector<std::vector<ExpiryEntry>> ring_;
  /// Bit i: bucket i holds entries.
  std::array<std::uint64_t, kBuckets / 64> filled_{};
  std::size_t ring_size_ = 0;
  /// At or before the key of the latest pop's t (never ahead of time, so
  /// that pushes do not pile into its bucket).
  std::int64_t cursor_ = 0;
  /// The cursor's bucket is in descending order (a frame takes its due
  /// entries from the back); a push into it, or a new cursor, clears this.
  bool cursor_sorted_ = false;
  /// Entries of keys at or beyond cursor_ + kBuckets, a heap with the
  /// earliest at its front: as the cursor comes within reach they join the
  /// ring one by one, each moved once.
  std::vector<ExpiryEntry> far_;
  double earliest_ = std::numeric_limits<double>::infinity();  ///< Least expiry of all.
};

}  // namespace voxvis::detail
