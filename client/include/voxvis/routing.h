// voxvis/routing.h — which server of a fleet owns a scene: rendezvous
// (highest random weight) hashing over the fleet's shard names.
//
// A fleet is a list of shards, each a name and an address. Scene S belongs
// to the shard N with the largest weight(N, S), where weight is the first 8
// bytes, read big-endian, of SHA-256 over the UTF-8 bytes of N, a newline
// (0x0A) and S. Equal weights (never seen in practice) go to the smaller
// name. Any client in any language computes the same owner from the same
// names (docs/deploy.md gives the definition with a Python line), and
// voxvis-server started with --shard/--fleet refuses scenes whose owner is
// another shard, naming it.
//
// Why rendezvous hashing: no table to keep or share (Kubernetes does placement
// and restarts; a client only picks), and when a shard joins or leaves only
// the scenes it gains or held change owner — about 1/N of them — which is what
// `voxvis rebalance` then moves.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace voxvis::routing {

struct Shard {
  std::string name;     ///< The shard's name in the fleet, hashed.
  std::string address;  ///< HOST:PORT the client connects to.
};

/// The weight of scene `scene_id` on shard `shard_name` (see above).
std::uint64_t weight(std::string_view shard_name, std::string_view scene_id);

/// The index in `names` of the shard that owns `scene_id`; `names` must not
/// be empty.
std::size_t owner(const std::vector<std::string>& names, std::string_view scene_id);
std::size_t owner(const std::vector<Shard>& shards, std::string_view scene_id);

/// Whether `name` may name a shard: 1-253 printable ASCII characters without
/// white space, ',' or '='. On error sets `message`.
bool valid_shard_name(std::string_view name, std::string* message);

/// Parses a server list "[NAME=]HOST:PORT,..." (the --servers option). An
/// entry without NAME is named by its host's first DNS label when the host
/// is a DNS name ("voxvis-1.voxvis.default.svc:50051" is shard "voxvis-1",
/// a StatefulSet pod's name), and by the whole HOST:PORT when the host is an
/// IP address or "localhost". Errors (empty entries, a missing port, a name
/// given twice, more than 4096 entries) name the entry; on error returns
/// false and sets `message`.
bool parse_servers(std::string_view list, std::vector<Shard>* shards, std::string* message);

}  // namespace voxvis::routing
