// shard.h — the server's place in a fleet (--shard NAME --fleet NAME,...):
// which scene ids are its own. Clients route each scene to its owner by
// rendezvous hashing over the fleet's names (voxvis/routing.h); a server
// with an identity refuses the others' scenes with FAILED_PRECONDITION
// naming the owner, so that a client with a stale or wrong list is told
// where to go instead of silently creating a second copy elsewhere.
// Without --shard every scene is the server's own.
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include <grpcpp/grpcpp.h>

namespace voxvis::server {

class ShardIdentity {
 public:
  /// No identity: every scene is this server's.
  ShardIdentity() = default;
  /// This server is shard `self` of `fleet` (every shard's name, each once).
  /// A `self` not in `fleet` is a shard leaving the fleet (draining): every
  /// scene is another's. On error returns false and sets `error`, naming the
  /// option.
  static bool make(const std::string& self, const std::vector<std::string>& fleet, ShardIdentity* out,
                   std::string* error);

  bool enabled() const { return !self_.empty(); }
  /// Not in the fleet: serves nothing, keeps its scenes for `voxvis rebalance --drain`.
  bool draining() const { return draining_; }
  const std::string& self() const { return self_; }
  /// The name of the shard that owns `scene_id` when it is not this server;
  /// empty when it is this server's (always, without an identity).
  std::string other_owner(std::string_view scene_id) const;
  /// FAILED_PRECONDITION: scene `scene_id` belongs to shard `owner`.
  grpc::Status refusal(const std::string& scene_id, const std::string& owner) const;
  /// FAILED_PRECONDITION: a move's export or delete (only_if_misplaced) of
  /// scene `scene_id`, which this server serves as its own: it may still
  /// acknowledge moves, so it is not moved.
  grpc::Status still_served(const std::string& scene_id) const;
  /// "shard voxvis-0 of 3 (voxvis-0,voxvis-1,voxvis-2)".
  std::string describe() const;

 private:
  std::string self_;
  std::vector<std::string> fleet_;
  bool draining_ = false;
};

}  // namespace voxvis::server
