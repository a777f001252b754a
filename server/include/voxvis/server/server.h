// server.h — voxvis-server assembled: configuration, start-up (data directory,
// --scene files, TLS, tokens, metrics), the periodic position saver, and
// graceful shutdown. main.cpp only parses arguments and waits for a signal.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "voxvis/scene.h"

namespace voxvis::server {

struct ServerConfig {
  std::string listen = "127.0.0.1:50051";  ///< host:port; port 0 picks a free one.
  std::string data_dir;                     ///< Required: scenes and positions live here.
  std::vector<std::string> scene_files;     ///< Created at start unless the data dir has the id.
  std::string tls_cert, tls_key;            ///< PEM files; both or neither.
  std::string tokens_file;                  ///< Empty: no authentication.
  std::string metrics_address;              ///< Empty: no Prometheus endpoint.
  std::string port_file;                    ///< Written with the bound port once serving.
  std::uint64_t memory_budget_bytes = 0;    ///< 0: half of the machine's memory.
  double save_period_s = 2.0;               ///< Seconds between position saves, > 0.
  unsigned workers = 0;                     ///< 0: one per core.
  int max_message_bytes = 64 << 20;         ///< Largest message accepted, bytes.
  /// Memory gRPC may use for its buffers (ResourceQuota); 0: the larger of
  /// 256 MiB and four largest messages.
  std::uint64_t grpc_memory_bytes = 0;
  int max_streams_per_connection = 256;     ///< HTTP/2 concurrent streams per connection.
  int max_calls = 4096;                     ///< Calls in progress, server-wide.
  double shutdown_grace_s = 5.0;            ///< How long in-flight calls may take at shutdown.
  double max_view_lead_s = 1.0;             ///< How far viewers may run beyond the simulation's clock.
  double max_time_step_s = 3600.0;          ///< How far one simulation batch may advance the clock.
  bool reflection = false;                  ///< Serve gRPC server reflection (it needs no token).
  /// This server's shard name and every shard's (--shard, --fleet; both or
  /// neither): it then serves only the scenes rendezvous hashing gives it
  /// (src/scenes/shard.h).
  std::string shard;
  std::vector<std::string> fleet;
  /// Options of every scene the server builds (--scene files, CreateScene,
  /// the data directory's scenes at start); occlusion_buffer is
  /// --occlusion-buffer. Checked by start() before anything is loaded.
  SceneOptions scene_options;
  /// Verify mode: this fraction of served frames is rendered on a background
  /// thread (EGL) and checked; 0: off. [0, 1].
  double verify_fraction = 0.0;
  std::string verify_resolution = "320x180";  ///< WxH of the verify renders.
  int verify_queue = 64;                      ///< Frames waiting at most; more are dropped.
  std::string egl_platform = "auto";          ///< auto, device or surfaceless.
  int egl_device = -1;                        ///< -1: a GPU if any, else the software device.
};

class Server {
 public:
  using Log = std::function<void(const std::string&)>;
  /// Starts serving. On error returns null and sets `error` to a message that
  /// names the option or file at fault.
  static std::unique_ptr<Server> start(const ServerConfig& config, Log log, std::string* error);
  virtual ~Server() = default;
  /// The port bound (useful with port 0).
  virtual int port() const = 0;
  /// Graceful shutdown: refuse new calls, answer in-flight frames, end the
  /// streams with UNAVAILABLE, save positions. Idempotent.
  virtual void shutdown() = 0;
};

}  // namespace voxvis::server
