// Reading the server's cost counters from its Prometheus text (loadgen --metrics).
#include <string>

#include <gtest/gtest.h>

#include "server_usage.h"

namespace voxvis::cli {
namespace {

// As prometheus-cpp writes it: HELP/TYPE comments, labelled series, several scenes.
const char* const kText = R"(# HELP voxvis_frames_total Frames computed
# TYPE voxvis_frames_total counter
voxvis_frames_total{scene="indoor"} 1200
voxvis_frames_total{scene="indoor2"} 7
voxvis_frames_total{scene="xindoor"} 9
# TYPE voxvis_frame_engine_seconds histogram
voxvis_frame_engine_seconds_count{scene="indoor"} 1200
voxvis_frame_engine_seconds_sum{scene="indoor2"} 0.5
voxvis_frame_engine_seconds_sum{scene="indoor"} 0.25
voxvis_frame_engine_seconds_bucket{scene="indoor",le="5e-05"} 3
# TYPE process_cpu_seconds_total counter
process_cpu_seconds_total 12.5
)";

TEST(ServerUsage, ReadsTheScenesSeriesAndTheProcessCpu) {
  ServerUsage u;
  std::string error;
  ASSERT_TRUE(parse_server_usage(kText, "indoor", &u, &error)) << error;
  EXPECT_EQ(u.frames, 1200.0);
  EXPECT_EQ(u.engine_seconds, 0.25);
  EXPECT_EQ(u.cpu_seconds, 12.5);
  ASSERT_TRUE(parse_server_usage(kText, "indoor2", &u, &error)) << error;
  EXPECT_EQ(u.frames, 7.0);
  EXPECT_EQ(u.engine_seconds, 0.5);
}

TEST(ServerUsage, PrefersTheEnginesCpuTime) {
  const std::string text = std::string(kText) +
                           "voxvis_frame_engine_cpu_seconds_total{scene=\"indoor\"} 0.125\n"
                           "voxvis_frame_engine_cpu_seconds_total{scene=\"indoor2\"} 0.375\n";
  ServerUsage u;
  std::string error;
  ASSERT_TRUE(parse_server_usage(text, "indoor", &u, &error)) << error;
  EXPECT_EQ(u.engine_seconds, 0.125);
  ASSERT_TRUE(parse_server_usage(text, "indoor2", &u, &error)) << error;
  EXPECT_EQ(u.engine_seconds, 0.375);
}

TEST(ServerUsage, NamesTheMissingSeries) {
  ServerUsage u;
  std::string error;
  EXPECT_FALSE(parse_server_usage(kText, "city", &u, &error));
  EXPECT_NE(error.find("voxvis_frame_engine_seconds_sum for scene 'city'"), std::string::npos) << error;
  const std::string old_server = std::string(kText).substr(0, std::string(kText).find("# TYPE process"));
  EXPECT_FALSE(parse_server_usage(old_server, "indoor", &u, &error));
  EXPECT_NE(error.find("no process_cpu_seconds_total"), std::string::npos) << error;
  EXPECT_FALSE(parse_server_usage("process_cpu_seconds_total nonsense\n", "indoor", &u, &error));
  EXPECT_NE(error.find("no process_cpu_seconds_total"), std::string::npos) << error;
}

TEST(ServerUsage, ScrapeNamesWhatFailed) {
  ServerUsage u;
  std::string error;
  // Port 1 on loopback: nothing listens there (and it needs no privilege to try).
  EXPECT_FALSE(scrape_server_usage("127.0.0.1:1", "indoor", &u, &error));
  EXPECT_NE(error.find("cannot read http://127.0.0.1:1/metrics"), std::string::npos) << error;
}

}  // namespace
}  // namespace voxvis::cli
