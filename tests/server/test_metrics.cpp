// Prometheus metrics as a scraper sees them: over HTTP, in the text format.
#include <gtest/gtest.h>

#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "scenes/metrics.h"
#include "server_process.h"

namespace voxvis::server {
namespace {

std::string scrape(int port) { return servertest::http_get(port, "/metrics"); }

bool contains(const std::string& text, const std::string& needle) {
  return text.find(needle) != std::string::npos;
}

TEST(Metrics, NullMetricsAcceptEverything) {
  auto metrics = make_null_metrics();
  auto scene = metrics->scene("a");
  ASSERT_TRUE(scene);
  scene->frame(FrameStats{}, 0.001);
  scene->skipped(1);
  scene->moves(2);
  scene->wake_size(3);
  scene->tbvs_active(4);
  scene->viewers(1);
  metrics->scenes(1);
  metrics->error("View", grpc::StatusCode::INTERNAL);
  metrics->remove_scene("a");
  scene->frame(FrameStats{}, 0.001);  // a handle outliving its scene is harmless
  EXPECT_EQ(metrics->port(), 0);
}

TEST(Metrics, ServedOverHttpAndRemovedWithTheScene) {
  auto metrics = make_prometheus_metrics("127.0.0.1:0");
  const int port = metrics->port();
  ASSERT_GT(port, 0);

  auto a = metrics->scene("a");
  auto b = metrics->scene("b");
  EXPECT_EQ(metrics->scene("a"), a) << "one handle per scene";
  FrameStats stats;
  stats.pvs_size = 30;
  stats.voxels_visited = 1500;
  stats.time_us = 250.0;
  a->frame(stats, 0.0004);
  a->skipped(3);
  a->moves(10);
  a->moves(0);
  a->wake_size(12);
  a->tbvs_active(5);
  a->viewers(1);
  a->viewers(1);
  a->viewers(-1);
  b->frame(stats, 0.5);
  b->frame(stats, 0.5);
  metrics->scenes(2);
  metrics->error("Simulate", grpc::StatusCode::INVALID_ARGUMENT);
  metrics->error("Simulate", grpc::StatusCode::INVALID_ARGUMENT);
  metrics->error("View", grpc::StatusCode::UNAUTHENTICATED);

  std::string text = scrape(port);
  EXPECT_TRUE(contains(text, "200 OK")) << text;
  EXPECT_TRUE(contains(text, "voxvis_frames_total{scene=\"a\"} 1\n")) << text;
  EXPECT_TRUE(contains(text, "voxvis_frames_total{scene=\"b\"} 2\n")) << text;
  EXPECT_TRUE(contains(text, "voxvis_frames_skipped_total{scene=\"a\"} 3\n")) << text;
  EXPECT_TRUE(contains(text, "voxvis_moves_total{scene=\"a\"} 10\n")) << text;
  EXPECT_TRUE(contains(text, "voxvis_wake_size{scene=\"a\"} 12\n")) << text;
  EXPECT_TRUE(contains(text, "voxvis_tbvs_active{scene=\"a\"} 5\n")) << text;
  EXPECT_TRUE(contains(text, "voxvis_viewers{scene=\"a\"} 1\n")) << text;
  EXPECT_TRUE(contains(text, "voxvis_scenes 2\n")) << text;
  EXPECT_TRUE(contains(text, "voxvis_errors_total{code=\"INVALID_ARGUMENT\",method=\"Simulate\"} 2\n"))
      << text;
  EXPECT_TRUE(contains(text, "voxvis_errors_total{code=\"UNAUTHENTICATED\",method=\"View\"} 1\n"))
      << text;
  // Buckets: 0.4 ms latency lands in le=0.0005 but not le=0.0002; the
  // engine's 250 µs likewise; 30 objects in le=50 not le=20; 1500 voxels in
  // le=2000 not le=1000.
  EXPECT_TRUE(contains(text, "voxvis_frame_latency_seconds_bucket{scene=\"a\",le=\"0.0002\"} 0\n"))
      << text;
  EXPECT_TRUE(contains(text, "voxvis_frame_latency_seconds_bucket{scene=\"a\",le=\"0.0005\"} 1\n"))
      << text;
  EXPECT_TRUE(contains(text, "voxvis_frame_latency_seconds_bucket{scene=\"a\",le=\"5e-05\"} 0\n"))
      << text;
  EXPECT_TRUE(contains(text, "voxvis_frame_engine_seconds_bucket{scene=\"a\",le=\"0.0002\"} 0\n"))
      << text;
  EXPECT_TRUE(contains(text, "voxvis_frame_engine_seconds_bucket{scene=\"a\",le=\"0.0005\"} 1\n"))
      << text;
  EXPECT_TRUE(contains(text, "voxvis_pvs_size_bucket{scene=\"a\",le=\"20\"} 0\n")) << text;
  EXPECT_TRUE(contains(text, "voxvis_pvs_size_bucket{scene=\"a\",le=\"50\"} 1\n")) << text;
  EXPECT_TRUE(contains(text, "voxvis_pvs_size_bucket{scene=\"a\",le=\"100000\"} 1\n")) << text;
  EXPECT_TRUE(contains(text, "voxvis_voxels_visited_bucket{scene=\"a\",le=\"1000\"} 0\n")) << text;
  EXPECT_TRUE(contains(text, "voxvis_voxels_visited_bucket{scene=\"a\",le=\"2000\"} 1\n")) << text;
  EXPECT_TRUE(contains(text, "voxvis_voxels_visited_bucket{scene=\"a\",le=\"10000000\"} 1\n"))
      << text;
  EXPECT_TRUE(contains(text, "voxvis_frame_latency_seconds_bucket{scene=\"a\",le=\"1\"} 1\n"))
      << text;

  metrics->remove_scene("a");
  a->frame(stats, 0.001);  // a late call on a removed scene's handle is a no-op
  a->viewers(-1);
  text = scrape(port);
  EXPECT_TRUE(contains(text, "200 OK")) << text;
  EXPECT_FALSE(contains(text, "scene=\"a\"")) << text;
  EXPECT_TRUE(contains(text, "voxvis_frames_total{scene=\"b\"} 2\n")) << text;

  // A scene created again under the same id starts from zero.
  auto a2 = metrics->scene("a");
  EXPECT_NE(a2, a);
  a2->frame(stats, 0.001);
  text = scrape(port);
  EXPECT_TRUE(contains(text, "voxvis_frames_total{scene=\"a\"} 1\n")) << text;
}

TEST(Metrics, ConcurrentRecordingLosesNothing) {
  auto metrics = make_prometheus_metrics("127.0.0.1:0");
  auto scene = metrics->scene("c");
  constexpr int kThreads = 8, kPerThread = 5000;
  std::vector<std::thread> threads;
  for (int i = 0; i < kThreads; ++i) {
    threads.emplace_back([&] {
      for (int j = 0; j < kPerThread; ++j) {
        scene->frame(FrameStats{}, 0.001);
        scene->viewers(1);
        scene->moves(2);
        scene->viewers(-1);
      }
    });
  }
  for (auto& t : threads) t.join();
  const std::string text = scrape(metrics->port());
  EXPECT_TRUE(contains(text, "voxvis_frames_total{scene=\"c\"} 40000\n")) << text;
  EXPECT_TRUE(contains(text, "voxvis_moves_total{scene=\"c\"} 80000\n")) << text;
  EXPECT_TRUE(contains(text, "voxvis_viewers{scene=\"c\"} 0\n")) << text;
}

TEST(Metrics, RemoveWhileRecordingIsSafe) {
  // Run under the sanitizers this catches a use after Family::Remove.
  auto metrics = make_prometheus_metrics("127.0.0.1:0");
  for (int round = 0; round < 20; ++round) {
    auto scene = metrics->scene("r");
    std::thread recorder([scene] {
      for (int j = 0; j < 2000; ++j) scene->frame(FrameStats{}, 0.001);
    });
    metrics->remove_scene("r");
    recorder.join();
  }
  EXPECT_FALSE(contains(scrape(metrics->port()), "scene=\"r\""));
}

TEST(Metrics, UnusableAddressThrowsNamingIt) {
  for (const std::string address : {"256.0.0.1:1", "127.0.0.1:99999"}) {
    try {
      make_prometheus_metrics(address);
      ADD_FAILURE() << "no exception for " << address;
    } catch (const std::runtime_error& e) {
      EXPECT_TRUE(contains(e.what(), address)) << e.what();
    }
  }
  // A port already in use.
  auto first = make_prometheus_metrics("127.0.0.1:0");
  const std::string busy = "127.0.0.1:" + std::to_string(first->port());
  try {
    make_prometheus_metrics(busy);
    ADD_FAILURE() << "no exception for " << busy;
  } catch (const std::runtime_error& e) {
    EXPECT_TRUE(contains(e.what(), busy)) << e.what();
  }
}

}  // namespace
}  // namespace voxvis::server
