// server_usage.h — the server's own cost per answer, from its Prometheus
// metrics (voxvis-server --metrics ADDR): `voxvis loadgen --metrics ADDR`
// reads them before and after a run and divides the differences.
#pragma once

#include <string>

namespace voxvis::cli {

/// Counters of a server at one instant, for one scene.
struct ServerUsage {
  double cpu_seconds = 0.0;     ///< process_cpu_seconds_total: the whole process, user + system.
  double engine_seconds = 0.0;  ///< voxvis_frame_engine_cpu_seconds_total{scene}: CPU time of its frames'
                                ///< engine calls (servers without it: voxvis_frame_engine_seconds_sum, their time).
  double frames = 0.0;          ///< voxvis_frames_total{scene}: answers computed.
};

/// Reads the counters of `scene` from a Prometheus text exposition. False
/// with `error` naming the series when one is missing (a server without
/// process metrics, or a scene it does not have).
bool parse_server_usage(const std::string& text, const std::string& scene, ServerUsage* out,
                        std::string* error);

/// GETs http://`address`/metrics (libcurl, 5 s timeout) and parses it. False
/// with `error` saying what failed (connection, HTTP status, a missing series).
bool scrape_server_usage(const std::string& address, const std::string& scene, ServerUsage* out,
                         std::string* error);

}  // namespace voxvis::cli
