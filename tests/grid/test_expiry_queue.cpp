// The TBVs' expiry queue (grid/src/expiry_queue.h): against a reference that
// keeps every entry in one sorted list, over random pushes and frames —
// frames a bucket apart and within one bucket, entries pushed earlier than
// the last frame's time (renewed ahead), periods beyond the ring's span
// (frames far apart and at frame rate),
// jumps of hours, negative times — the queue answers the same due entries
// in the same order, and says the same whether anything is due.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <tuple>
#include <vector>

#include "expiry_queue.h"
#include "voxvis/rng.h"

namespace voxvis::test {
namespace {

using detail::ExpiryEntry;
using detail::ExpiryQueue;

bool before(const ExpiryEntry& a, const ExpiryEntry& b) {
  return std::tie(a.expiry, a.slot, a.epoch) < std::tie(b.expiry, b.slot, b.epoch);
}

/// Every entry in one list; due entries taken in order.
struct Reference {
  std::vector<ExpiryEntry> all;
  bool any_due(double t) const {
    return std::any_of(all.begin(), all.end(), [&](const ExpiryEntry& e) { return e.expiry <= t; });
  }
  std::vector<ExpiryEntry> pop_due(double t) {
    std::vector<ExpiryEntry> due;
    std::erase_if(all, [&](const ExpiryEntry& e) {
      if (e.expiry > t) return false;
      due.push_back(e);
      return true;
    });
    std::sort(due.begin(), due.end(), before);
    return due;
  }
};

struct QueueRun {
  double start = 0.0;
  double frame_dt = 1.0 / 60.0;
  double max_period = 12.0;
  double ahead = 0.0;        ///< Pops reach this far past the frame's time.
  double jump_chance = 0.0;  ///< A frame's chance of jumping hours ahead.
};

/// Runs both queues through `frames` frames: each pushes a few entries with
/// expiries in (t, t + max_period] (some just after t, some at t exactly
/// plus the least step) and pops what is due at t + ahead.
void run_against_reference(const QueueRun& r, int frames, std::uint64_t seed) {
  Rng rng(seed);
  ExpiryQueue q;
  Reference ref;
  double t = r.start;
  std::uint32_t slot = 0;
  for (int f = 0; f < frames; ++f) {
    t += rng.uniform() < r.jump_chance ? rng.uniform(3600.0, 7200.0) : r.frame_dt * rng.uniform(0.2, 1.8);
    const int pushes = rng.uniform_int(0, 12);
    for (int i = 0; i < pushes; ++i) {
      const double period = rng.uniform() < 0.1 ? 1e-3 : rng.uniform(1e-3, r.max_period);
      const ExpiryEntry e{std::nextafter(t, t + 1.0) + (rng.uniform() < 0.05 ? 0.0 : period), slot++,
                          static_cast<std::uint32_t>(rng.uniform_int(0, 3))};
      q.push(e, t);
      ref.all.push_back(e);
    }
    ASSERT_EQ(q.any_due(t), ref.any_due(t)) << "frame " << f << " t " << t;
    ASSERT_EQ(q.any_due(t + r.ahead), ref.any_due(t + r.ahead)) << "frame " << f;
    std::vector<ExpiryEntry> got;
    q.pop_due(t + r.ahead, &got);
    const std::vector<ExpiryEntry> want = ref.pop_due(t + r.ahead);
    ASSERT_EQ(got.size(), want.size()) << "frame " << f << " t " << t;
    for (std::size_t k = 0; k < got.size(); ++k) {
      ASSERT_EQ(got[k].expiry, want[k].expiry) << "frame " << f << " entry " << k;
      ASSERT_EQ(got[k].slot, want[k].slot) << "frame " << f << " entry " << k;
      ASSERT_EQ(got[k].epoch, want[k].epoch) << "frame " << f << " entry " << k;
    }
    ASSERT_EQ(q.size(), ref.all.size()) << "frame " << f;
  }
}

TEST(ExpiryQueue, EmptyQueueHasNothingDue) {
  ExpiryQueue q;
  EXPECT_TRUE(q.empty());
  EXPECT_FALSE(q.any_due(1e10));
  std::vector<ExpiryEntry> out;
  q.pop_due(1e10, &out);
  EXPECT_TRUE(out.empty());
}

TEST(ExpiryQueue, AnEntryIsDueAtItsExpiryAndNotBefore) {
  ExpiryQueue q;
  const double at = 10.0 + ExpiryQueue::kBucketSeconds / 3.0;  // Inside a bucket.
  q.push({at, 7, 1}, 0.0);
  EXPECT_FALSE(q.any_due(std::nextafter(at, 0.0)));
  std::vector<ExpiryEntry> out;
  q.pop_due(std::nextafter(at, 0.0), &out);
  EXPECT_TRUE(out.empty());
  EXPECT_TRUE(q.any_due(at));
  q.pop_due(at, &out);
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(out[0].slot, 7u);
  EXPECT_TRUE(q.empty());
  EXPECT_FALSE(q.any_due(1e10));
}

TEST(ExpiryQueue, FramesAtSixtyHertzAgreeWithTheReference) { run_against_reference(QueueRun{}, 3000, 1); }

TEST(ExpiryQueue, FramesWithinOneBucketAgreeWithTheReference) {
  QueueRun r;
  r.frame_dt = ExpiryQueue::kBucketSeconds / 7.0;
  r.max_period = 0.5;
  run_against_reference(r, 3000, 2);
}

TEST(ExpiryQueue, RenewalsAheadOfTheFrameAgreeWithTheReference) {
  // Popping up to t + ahead moves the cursor past entries pushed later with
  // an expiry before t + ahead.
  QueueRun r;
  r.ahead = 0.1;
  r.max_period = 2.0;
  run_against_reference(r, 3000, 3);
}

TEST(ExpiryQueue, PeriodsBeyondTheRingAgreeWithTheReference) {
  QueueRun r;
  r.max_period = 3.0 * ExpiryQueue::kBucketSeconds * ExpiryQueue::kBuckets;
  r.frame_dt = 2.0;
  run_against_reference(r, 3000, 4);
}

TEST(ExpiryQueue, ManyLongPeriodsAtFrameRateAgreeWithTheReference) {
  // Frames at 60 Hz, most entries beyond the ring, joining it a few at a
  // time as the frames go.
  QueueRun r;
  r.max_period = 4.0 * ExpiryQueue::kBucketSeconds * ExpiryQueue::kBuckets;
  run_against_reference(r, 4000, 7);
}

TEST(ExpiryQueue, JumpsOfHoursAndNegativeTimesAgreeWithTheReference) {
  QueueRun r;
  r.start = -3e4;
  r.jump_chance = 0.02;
  r.max_period = 300.0;
  run_against_reference(r, 3000, 5);
}

TEST(ExpiryQueue, TimesAtTheSceneLimitAgreeWithTheReference) {
  QueueRun r;
  r.start = 1e10 - 1e3;
  r.max_period = 60.0;
  run_against_reference(r, 2000, 6);
}

}  // namespace
}  // namespace voxvis::test
