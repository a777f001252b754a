// main.cpp — `voxvis-server`: arguments, logging, and signals. Everything else
// is in server.cpp.
#include <signal.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <mutex>
#include <string>

#include <CLI/CLI.hpp>

#include "voxvis/server/server.h"

#ifndef VOXVIS_VERSION
#define VOXVIS_VERSION "unknown"
#endif

namespace {

std::mutex log_mu;

void log_line(const std::string& text) {
  const auto now = std::chrono::system_clock::now();
  const std::time_t secs = std::chrono::system_clock::to_time_t(now);
  std::tm tm{};
  gmtime_r(&secs, &tm);
  char stamp[32];
  std::strftime(stamp, sizeof stamp, "%Y-%m-%dT%H:%M:%SZ", &tm);
  std::lock_guard<std::mutex> lock(log_mu);
  std::fprintf(stderr, "%s voxvis-server: %s\n", stamp, text.c_str());
}

int run(int argc, char** argv) {
  voxvis::server::ServerConfig config;
  double budget_mib = 0.0, max_message_mib = 64.0, grpc_memory_mib = 0.0;
  CLI::App app{
      "voxvis-server — serves potentially visible sets over gRPC (proto/voxvis/v1/voxvis.proto).\n"
      "Scenes created through the API are kept in the data directory and loaded\n"
      "again at start; dynamic objects' positions are saved every save period."};
  app.name("voxvis-server");
  app.set_version_flag("--version", std::string("voxvis-server ") + VOXVIS_VERSION);
  app.add_option("--listen", config.listen, "Address to serve on, host:port (port 0: any free port)")
      ->capture_default_str();
  app.add_option("--data-dir", config.data_dir, "Directory for scenes and positions (created if missing)")
      ->required()
      ->type_name("DIR");
  app.add_option("--scene", config.scene_files,
                 "Scene file (voxvis-scene/1) to serve, as ID=FILE or FILE (id: the file name "
                 "without extension); kept as it is when the data directory already has that id")
      ->type_name("[ID=]FILE");
  app.add_option("--tls-cert", config.tls_cert, "Server certificate chain (PEM); enables TLS")
      ->type_name("FILE");
  app.add_option("--tls-key", config.tls_key, "Server private key (PEM)")->type_name("FILE");
  app.add_option("--tokens", config.tokens_file,
                 "Bearer tokens file: lines '<viewer|simulation|admin> <token>'; "
                 "without it every client may do everything")
      ->type_name("FILE");
  app.add_option("--metrics", config.metrics_address,
                 "Serve Prometheus metrics at http://ADDR/metrics")
      ->type_name("ADDR");
  app.add_option("--memory-budget-mib", budget_mib,
                 "Memory all scenes' grids may use together, MiB (default: half the machine's)")
      ->type_name("MIB");
  app.add_option("--save-period", config.save_period_s,
                 "Seconds between saves of dynamic objects' positions")
      ->capture_default_str();
  app.add_option("--max-view-lead", config.max_view_lead_s,
                 "Seconds a viewer's frame may run beyond the time the simulation set; a later "
                 "frame time is taken as that limit (viewers do not own a scene's clock)")
      ->capture_default_str();
  app.add_option("--max-time-step", config.max_time_step_s,
                 "Seconds one simulation batch may advance a scene's clock (the first batch on "
                 "a scene may set it anywhere within ±1e10 s)")
      ->capture_default_str();
  app.add_option("--grpc-memory-mib", grpc_memory_mib,
                 "Memory gRPC may use for message buffers, all connections together, MiB "
                 "(default: the larger of 256 and four --max-message-mib)")
      ->type_name("MIB");
  app.add_option("--max-calls", config.max_calls,
                 "Calls in progress at once, server-wide; more are refused with RESOURCE_EXHAUSTED")
      ->capture_default_str();
  app.add_option("--max-streams-per-connection", config.max_streams_per_connection,
                 "Concurrent calls per client connection (HTTP/2); more wait in the client")
      ->capture_default_str();
  app.add_option("--workers", config.workers, "Worker threads for frames and moves (0: one per core)")
      ->capture_default_str();
  app.add_option("--max-message-mib", max_message_mib, "Largest message accepted or sent, MiB")
      ->capture_default_str();
  app.add_option("--occlusion-buffer", config.scene_options.occlusion_buffer,
                 "Width in pixels of the conservative occlusion buffer of every scene served "
                 "(8..4096, or 0: off; default 160); the same answers as `voxvis replay "
                 "--occlusion-buffer`")
      ->type_name("PIXELS")
      ->capture_default_str();
  app.add_option("--verify-fraction", config.verify_fraction,
                 "Verify this fraction of served frames in the background with EGL (0..1; 0: off); "
                 "misses are counted in the metrics and logged")
      ->type_name("F")
      ->capture_default_str();
  app.add_option("--verify-resolution", config.verify_resolution, "Pixels of the verify renders")
      ->type_name("WxH")
      ->capture_default_str();
  app.add_option("--verify-queue", config.verify_queue,
                 "Sampled frames waiting for the verifier at most; more are dropped (counted)")
      ->type_name("N")
      ->capture_default_str();
  app.add_option("--egl-platform", config.egl_platform, "EGL platform of the verify mode: auto, device, surfaceless")
      ->type_name("NAME")
      ->capture_default_str();
  app.add_option("--egl-device", config.egl_device,
                 "EGL device of the verify mode; default: a GPU if any, else the software one")
      ->type_name("N");
  app.add_flag("--reflection", config.reflection,
               "Serve gRPC server reflection, which answers without a token: trusted networks only");
  app.add_option("--shard", config.shard,
                 "This server's name in a fleet (a StatefulSet pod's name); with --fleet it serves "
                 "only the scenes rendezvous hashing gives it and refuses the others, naming their "
                 "shard (docs/deploy.md)")
      ->type_name("NAME");
  app.add_option("--fleet", config.fleet,
                 "Every shard's name, comma-separated: the names clients route over (voxvis "
                 "--servers). A --shard not among them is leaving the fleet (draining): it serves "
                 "no scene and keeps its data directory's for voxvis rebalance --drain")
      ->delimiter(',')
      ->type_name("NAME,...");
  app.add_option("--port-file", config.port_file,
                 "Write the bound port to this file once serving (for scripts, with port 0)")
      ->type_name("FILE");
  app.footer(
      "Stops gracefully on SIGTERM or SIGINT: in-flight frames are answered, streams end\n"
      "with UNAVAILABLE, positions are saved, exit status 0.\n"
      "Exit status: 0 after a graceful stop, 2 bad arguments or start-up error.");
  app.failure_message([](const CLI::App*, const CLI::Error& e) {
    return std::string("voxvis-server: error: ") + e.what() + "\nRun with --help for more information.\n";
  });
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  if (!std::isfinite(budget_mib) || budget_mib < 0) {
    std::fprintf(stderr, "voxvis-server: error: --memory-budget-mib: must be >= 0\n");
    return 2;
  }
  if (!std::isfinite(max_message_mib) || max_message_mib < 0.001 || max_message_mib > 2047) {
    std::fprintf(stderr, "voxvis-server: error: --max-message-mib: must be in [0.001, 2047]\n");
    return 2;
  }
  if (!std::isfinite(grpc_memory_mib) || grpc_memory_mib < 0 || grpc_memory_mib > 1048576) {
    std::fprintf(stderr, "voxvis-server: error: --grpc-memory-mib: must be in [0, 1048576]\n");
    return 2;
  }
  config.grpc_memory_bytes = static_cast<std::uint64_t>(grpc_memory_mib * 1048576.0);
  config.memory_budget_bytes = static_cast<std::uint64_t>(budget_mib * 1048576.0);
  config.max_message_bytes = static_cast<int>(max_message_mib * 1048576.0);

  // Signals are taken by sigwait on this thread only: block them before any
  // thread starts so that every thread inherits the mask.
  sigset_t stop_signals;
  sigemptyset(&stop_signals);
  sigaddset(&stop_signals, SIGTERM);
  sigaddset(&stop_signals, SIGINT);
  pthread_sigmask(SIG_BLOCK, &stop_signals, nullptr);
  signal(SIGPIPE, SIG_IGN);

  std::string error;
  auto server = voxvis::server::Server::start(config, log_line, &error);
  if (!server) {
    std::fprintf(stderr, "voxvis-server: error: %s\n", error.c_str());
    return 2;
  }
  int sig = 0;
  sigwait(&stop_signals, &sig);
  log_line(std::string("received ") + (sig == SIGTERM ? "SIGTERM" : "SIGINT") + ", stopping");
  server->shutdown();
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return run(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "voxvis-server: internal error: %s\n", e.what());
  } catch (...) {
    std::fprintf(stderr, "voxvis-server: internal error\n");
  }
  return 1;
}
