// The worker pool and strands: a scene's jobs never overlap and run in the
// order posted; different strands run in parallel; drain waits for all.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <thread>
#include <vector>

#include "pool.h"

namespace voxvis::server {
namespace {

TEST(Strand, JobsOfOneStrandNeverOverlapAndKeepTheirOrder) {
  WorkerPool pool(4);
  auto strand = std::make_shared<Strand>(pool);
  std::atomic<int> inside{0};
  std::atomic<int> overlaps{0};
  std::vector<int> order;  // Written only by the strand's jobs.
  constexpr int kJobs = 2000;
  // Posted from several threads at once, as reactors do.
  std::vector<std::thread> posters;
  std::atomic<int> next{0};
  std::mutex post_mu;  // Makes "posted order" well defined across posters.
  for (int p = 0; p < 3; ++p) {
    posters.emplace_back([&] {
      for (;;) {
        std::lock_guard<std::mutex> lock(post_mu);
        const int i = next.fetch_add(1);
        if (i >= kJobs) return;
        strand->post([&, i](Scratch&) {
          if (inside.fetch_add(1) != 0) overlaps.fetch_add(1);
          order.push_back(i);
          inside.fetch_sub(1);
        });
      }
    });
  }
  for (std::thread& t : posters) t.join();
  pool.drain();
  EXPECT_EQ(overlaps.load(), 0);
  ASSERT_EQ(order.size(), static_cast<std::size_t>(kJobs));
  for (int i = 0; i < kJobs; ++i) ASSERT_EQ(order[static_cast<std::size_t>(i)], i);
}

TEST(Strand, DifferentStrandsRunInParallel) {
  WorkerPool pool(2);
  auto a = std::make_shared<Strand>(pool);
  auto b = std::make_shared<Strand>(pool);
  // Each job waits (bounded) for the other strand's job to start: only
  // parallel execution lets both see each other.
  std::atomic<bool> a_started{false}, b_started{false};
  std::atomic<bool> a_saw_b{false}, b_saw_a{false};
  const auto wait_for = [](std::atomic<bool>& flag) {
    const auto end = std::chrono::steady_clock::now() + std::chrono::seconds(10);
    while (!flag.load() && std::chrono::steady_clock::now() < end)
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    return flag.load();
  };
  a->post([&](Scratch&) {
    a_started = true;
    a_saw_b = wait_for(b_started);
  });
  b->post([&](Scratch&) {
    b_started = true;
    b_saw_a = wait_for(a_started);
  });
  pool.drain();
  EXPECT_TRUE(a_saw_b.load());
  EXPECT_TRUE(b_saw_a.load());
}

TEST(WorkerPool, DrainWaitsForJobsThatPostMoreJobs) {
  WorkerPool pool(2);
  auto strand = std::make_shared<Strand>(pool);
  std::atomic<int> done{0};
  for (int i = 0; i < 50; ++i) {
    pool.submit([&](Scratch&) {
      strand->post([&](Scratch&) {
        std::this_thread::sleep_for(std::chrono::microseconds(200));
        done.fetch_add(1);
      });
    });
  }
  pool.drain();
  EXPECT_EQ(done.load(), 50);
}

TEST(WorkerPool, DestructorRunsQueuedJobs) {
  std::atomic<int> done{0};
  {
    WorkerPool pool(1);
    for (int i = 0; i < 100; ++i) pool.submit([&](Scratch&) { done.fetch_add(1); });
  }
  EXPECT_EQ(done.load(), 100);
}

}  // namespace
}  // namespace voxvis::server
