// service_config.h — the Visibility service's settings (voxvis-server's
// options; docs/server.md), read by the layers that serve calls.
#pragma once

#include <cstdint>

#include "scenes/shard.h"
#include "voxvis/scene.h"

namespace voxvis::server {

struct ServiceConfig {
  SceneOptions scene_options;
  std::uint64_t memory_budget_bytes = 0;  ///< Sum of scenes' estimated bytes allowed.
  unsigned workers = 1;
  /// How far beyond the simulation's clock a viewer's frame may run, seconds.
  double max_view_lead_s = 1.0;
  /// How far one simulation batch may advance a scene's clock, seconds.
  double max_time_step_s = 3600.0;
  /// Calls in progress (streams and unary calls), server-wide.
  int max_calls = 4096;
  /// Largest scene file a CreateScene from a description may be saved as
  /// (saved_scene_bytes): 4 x --max-message-mib, room for any description
  /// without instancing that fits a message, while a restart, which reads
  /// the file back, needs several times its size.
  std::uint64_t max_saved_scene_bytes = std::uint64_t{256} << 20;
  /// Largest message sent (--max-message-mib): an ExportScene answer above
  /// it is refused, naming the files to copy instead.
  std::uint64_t max_message_bytes = std::uint64_t{64} << 20;
  /// The server's place in a fleet (--shard, --fleet); none: every scene is its own.
  ShardIdentity shard;
};

}  // namespace voxvis::server
