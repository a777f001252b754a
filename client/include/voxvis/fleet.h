// voxvis/fleet.h — the client side of a fleet of voxvis-servers: one list of
// servers ("[NAME=]HOST:PORT,...", voxvis/routing.h), and for each scene the
// Client of the server that owns it. One channel per server (gRPC connects
// it at its first call); every call on a scene goes to its owner.
//
//   std::string error;
//   auto fleet = voxvis::client::Fleet::connect(
//       "voxvis-0.voxvis:50051,voxvis-1.voxvis:50051,voxvis-2.voxvis:50051", {}, &error);
//   const voxvis::client::Client& c = fleet->for_scene("match-17");
//   voxvis::client::ViewerSession viewer(c, "match-17");
//
// Kubernetes places and restarts the servers; the fleet only picks. A server
// started with --shard/--fleet refuses another shard's scene with
// FAILED_PRECONDITION naming its owner: a list that disagrees with the
// servers' shows at the first call.
//
// Thread-safety: as Client's (a Fleet may be shared between threads).
#pragma once

#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "voxvis/client.h"
#include "voxvis/routing.h"

namespace voxvis::client {

class Fleet {
 public:
  /// Parses `servers` (routing::parse_servers); `options` apply to every
  /// connection (its address is ignored; the TLS name, when TLS is on,
  /// defaults to each server's host). On error returns null and sets `error`.
  static std::unique_ptr<Fleet> connect(std::string_view servers, const ConnectOptions& options,
                                        std::string* error);

  const std::vector<routing::Shard>& shards() const { return shards_; }
  /// The index of the shard that owns `scene_id`.
  std::size_t owner(std::string_view scene_id) const { return routing::owner(shards_, scene_id); }
  /// The client of shard `index` (< shards().size()).
  const Client& at(std::size_t index) const { return *clients_.at(index); }
  /// The client of the server that owns `scene_id`.
  const Client& for_scene(std::string_view scene_id) const { return at(owner(scene_id)); }

 private:
  Fleet() = default;

  std::vector<routing::Shard> shards_;
  std::vector<std::unique_ptr<Client>> clients_;  // One per shard, in order.
};

}  // namespace voxvis::client
