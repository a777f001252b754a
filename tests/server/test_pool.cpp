// The worker pool and strands: a scene's jobs never overlap and run in the
// order posted; different strands run in parallel; drain waits for all; a
// job that throws stops neither the pool nor its strand; a strand knows
// when the calling thread runs its jobs (what its asserts rely on).
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "scenes/pool.h"

namespace voxvis::server {
namespace {

TEST(Strand, JobsOfOneStrandNeverOverlapAndKeepTheirOrder) {
  WorkerPool pool(4);
  auto strand = std::make_shared<Strand>(pool, "s");
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
  auto a = std::make_shared<Strand>(pool, "a");
  auto b = std::make_shared<Strand>(pool, "b");
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

TEST(Strand, RunsHereOnlyInsideItsOwnJobs) {
  WorkerPool pool(2);
  auto a = std::make_shared<Strand>(pool, "a");
  auto b = std::make_shared<Strand>(pool, "b");
  EXPECT_FALSE(a->runs_here());  // The test's own thread runs no job.
  std::atomic<int> in_a{0}, in_b{0}, a_in_b{0}, b_in_a{0}, plain_job{0};
  constexpr int kJobs = 50;
  for (int i = 0; i < kJobs; ++i) {
    a->post([&](Scratch&) {
      in_a += a->runs_here() ? 1 : 0;
      b_in_a += b->runs_here() ? 1 : 0;
    });
    b->post([&](Scratch&) {
      in_b += b->runs_here() ? 1 : 0;
      a_in_b += a->runs_here() ? 1 : 0;
    });
    // A job of the pool's own, on a worker that ran strands' jobs before.
    pool.submit("other", [&](Scratch&) { plain_job += (a->runs_here() || b->runs_here()) ? 1 : 0; });
  }
  pool.drain();
  EXPECT_EQ(in_a.load(), kJobs);
  EXPECT_EQ(in_b.load(), kJobs);
  EXPECT_EQ(a_in_b.load(), 0);
  EXPECT_EQ(b_in_a.load(), 0);
  EXPECT_EQ(plain_job.load(), 0);
  EXPECT_FALSE(a->runs_here());
}

TEST(WorkerPool, DrainWaitsForJobsThatPostMoreJobs) {
  WorkerPool pool(2);
  auto strand = std::make_shared<Strand>(pool, "s");
  std::atomic<int> done{0};
  for (int i = 0; i < 50; ++i) {
    pool.submit("c", [&](Scratch&) {
      strand->post([&](Scratch&) {
        std::this_thread::sleep_for(std::chrono::microseconds(200));
        done.fetch_add(1);
      });
    });
  }
  pool.drain();
  EXPECT_EQ(done.load(), 50);
}

// Before the pool caught them, the first throw ended the process
// (std::terminate) and a throwing strand job left the strand stuck.
TEST(WorkerPool, AJobThatThrowsIsReportedAndTheRestStillRun) {
  std::mutex mu;
  std::vector<std::string> errors;  // Guarded by mu.
  std::atomic<int> done{0};
  {
    WorkerPool pool(2, [&](const std::string& what) {
      std::lock_guard<std::mutex> lock(mu);
      errors.push_back(what);
    });
    auto strand = std::make_shared<Strand>(pool, "scene");
    for (int i = 0; i < 20; ++i) {
      pool.submit("c", [&, i](Scratch&) {
        if (i % 5 == 0) throw std::runtime_error("job " + std::to_string(i));
        done.fetch_add(1);
      });
      strand->post([&, i](Scratch&) {
        if (i % 4 == 0) throw 42;  // Not a std::exception.
        done.fetch_add(1);
      });
    }
    pool.drain();
    EXPECT_EQ(pool.failed(), 4u + 5u);
  }
  EXPECT_EQ(done.load(), 16 + 15);
  std::lock_guard<std::mutex> lock(mu);
  ASSERT_EQ(errors.size(), 9u);
  EXPECT_EQ(std::count(errors.begin(), errors.end(), "job 5"), 1);
  EXPECT_EQ(std::count(errors.begin(), errors.end(), "an exception that is not a std::exception"), 5);
}

TEST(WorkerPool, DestructorRunsQueuedJobs) {
  std::atomic<int> done{0};
  {
    WorkerPool pool(1);
    for (int i = 0; i < 100; ++i) pool.submit(i % 2 ? "a" : "b", [&](Scratch&) { done.fetch_add(1); });
  }
  EXPECT_EQ(done.load(), 100);
}

// One worker, a client with a backlog of 1,000 jobs, then one job from another
// client: the second client's job runs second, not after the backlog.
TEST(WorkerPool, ClientsTakeTurns) {
  WorkerPool pool(1);
  std::mutex mu;
  std::vector<std::string> ran;  // Guarded by mu.
  std::atomic<bool> release{false}, started{false};
  // The first job holds the only worker until everything is queued.
  pool.submit("flood", [&](Scratch&) {
    started.store(true);
    while (!release.load()) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    std::lock_guard<std::mutex> lock(mu);
    ran.push_back("flood");
  });
  while (!started.load()) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  for (int i = 0; i < 1000; ++i)
    pool.submit("flood", [&](Scratch&) {
      std::lock_guard<std::mutex> lock(mu);
      ran.push_back("flood");
    });
  pool.submit("viewer", [&](Scratch&) {
    std::lock_guard<std::mutex> lock(mu);
    ran.push_back("viewer");
  });
  pool.submit("other", [&](Scratch&) {
    std::lock_guard<std::mutex> lock(mu);
    ran.push_back("other");
  });
  EXPECT_EQ(pool.queued(), 1002u);
  release.store(true);
  pool.drain();
  EXPECT_EQ(pool.queued(), 0u);
  ASSERT_EQ(ran.size(), 1003u);
  // The held job, then one turn each in order of arrival: the flood's next
  // job, the viewer's, the other client's; then the rest of the flood.
  EXPECT_EQ(ran[1], "flood");
  EXPECT_EQ(ran[2], "viewer");
  EXPECT_EQ(ran[3], "other");
  for (std::size_t i = 4; i < ran.size(); ++i) EXPECT_EQ(ran[i], "flood") << i;
}

// Jobs of one client keep their order.
TEST(WorkerPool, OneClientsJobsRunInOrder) {
  WorkerPool pool(1);
  std::vector<int> order;  // Written by the only worker.
  for (int i = 0; i < 500; ++i) {
    pool.submit("a", [&order, i](Scratch&) { order.push_back(i); });
    pool.submit("b", [](Scratch&) {});
  }
  pool.drain();
  ASSERT_EQ(order.size(), 500u);
  for (int i = 0; i < 500; ++i) EXPECT_EQ(order[static_cast<std::size_t>(i)], i);
}

// Clients come and go (more than the pool keeps queues for): every job
// runs once, each client's in order, and turns still alternate.
TEST(WorkerPool, ManyClientsComingAndGoingKeepOrderAndTurns) {
  WorkerPool pool(1);
  std::mutex mu;
  std::vector<std::pair<int, int>> ran;  // (client, job), guarded by mu.
  std::atomic<bool> release{false}, started{false};
  pool.submit("hold", [&](Scratch&) {
    started.store(true);
    while (!release.load()) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  });
  while (!started.load()) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  constexpr int kClients = 700, kJobs = 3;  // Beyond kKeptQueues (256).
  for (int j = 0; j < kJobs; ++j)
    for (int c = 0; c < kClients; ++c)
      pool.submit("client-" + std::to_string(c), [&, c, j](Scratch&) {
        std::lock_guard<std::mutex> lock(mu);
        ran.emplace_back(c, j);
      });
  release.store(true);
  pool.drain();
  ASSERT_EQ(ran.size(), static_cast<std::size_t>(kClients * kJobs));
  // One turn each, in order of arrival, round after round.
  for (std::size_t i = 0; i < ran.size(); ++i) {
    EXPECT_EQ(ran[i].first, static_cast<int>(i % kClients)) << i;
    EXPECT_EQ(ran[i].second, static_cast<int>(i / kClients)) << i;
  }
  // Later, with every queue empty, new clients still run (the empty queues
  // are dropped to make room) and old ones too.
  ran.clear();
  for (int c = 0; c < 2 * kClients; ++c)
    pool.submit("later-" + std::to_string(c), [&, c](Scratch&) {
      std::lock_guard<std::mutex> lock(mu);
      ran.emplace_back(c, 0);
    });
  pool.submit("client-0", [&](Scratch&) {
    std::lock_guard<std::mutex> lock(mu);
    ran.emplace_back(-1, 0);
  });
  pool.drain();
  EXPECT_EQ(ran.size(), static_cast<std::size_t>(2 * kClients + 1));
}

// The ring keeps FIFO order across growth and wrap-around.
TEST(RingQueue, KeepsOrderAcrossGrowthAndWrapAround) {
  RingQueue<int> q;
  int pushed = 0, popped = 0;
  for (int round = 0; round < 50; ++round) {
    for (int i = 0; i < round % 13 + 1; ++i) q.push_back(pushed++);
    for (int i = 0; i < round % 7 + 1 && !q.empty(); ++i) {
      ASSERT_EQ(q.front(), popped++);
      q.pop_front();
    }
    ASSERT_EQ(q.size(), static_cast<std::size_t>(pushed - popped));
  }
  while (!q.empty()) {
    ASSERT_EQ(q.front(), popped++);
    q.pop_front();
  }
  EXPECT_EQ(popped, pushed);
}

}  // namespace
}  // namespace voxvis::server
