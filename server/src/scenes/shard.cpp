#include "scenes/shard.h"

#include <set>

#include "voxvis/routing.h"

namespace voxvis::server {

bool ShardIdentity::make(const std::string& self, const std::vector<std::string>& fleet, ShardIdentity* out,
                         std::string* error) {
  *out = ShardIdentity();
  if (self.empty() && fleet.empty()) return true;
  if (self.empty() || fleet.empty()) {
    *error = "--shard and --fleet go together (this server's name, and every shard's)";
    return false;
  }
  std::string why;
  if (!routing::valid_shard_name(self, &why)) {
    *error = "--shard: " + why;
    return false;
  }
  std::set<std::string> seen;
  for (const std::string& name : fleet) {
    if (!routing::valid_shard_name(name, &why)) {
      *error = "--fleet: " + why;
      return false;
    }
    if (!seen.insert(name).second) {
      *error = "--fleet: shard '" + name + "' is listed twice";
      return false;
    }
  }
  if (fleet.size() > 4096) {
    *error = "--fleet: more than 4096 shards";
    return false;
  }
  out->draining_ = !seen.count(self);
  out->self_ = self;
  out->fleet_ = fleet;
  return true;
}

std::string ShardIdentity::other_owner(std::string_view scene_id) const {
  if (!enabled()) return {};
  const std::string& owner = fleet_[routing::owner(fleet_, scene_id)];
  return owner == self_ ? std::string() : owner;
}

grpc::Status ShardIdentity::refusal(const std::string& scene_id, const std::string& owner) const {
  return grpc::Status(grpc::StatusCode::FAILED_PRECONDITION,
                      "scene_id: scene '" + scene_id + "' belongs to shard '" + owner + "', not to this server ('" +
                          self_ + (draining_ ? "', draining, not in" : "' of") + " a fleet of " +
                          std::to_string(fleet_.size()) +
                          "); send it there: clients route by rendezvous hashing over the fleet's names "
                          "(voxvis --servers, docs/deploy.md)");
}

grpc::Status ShardIdentity::still_served(const std::string& scene_id) const {
  const std::string self =
      enabled() ? "shard '" + self_ + "', whose --fleet makes it the scene's owner" : "a server without --shard, which serves every scene";
  return grpc::Status(grpc::StatusCode::FAILED_PRECONDITION,
                      "scene_id: scene '" + scene_id + "' is served here (" + self +
                          "), not kept for another shard: it may still acknowledge moves, so it is not moved; "
                          "restart this server with the fleet's --fleet first, then move it (docs/deploy.md)");
}

std::string ShardIdentity::describe() const {
  std::string names;
  for (const std::string& n : fleet_) names += (names.empty() ? "" : ",") + n;
  if (draining_)
    return "shard '" + self_ + "', draining: not in the fleet of " + std::to_string(fleet_.size()) + " (" + names +
           "), it serves no scene and keeps its data directory's for `voxvis rebalance --drain`";
  return "shard '" + self_ + "' of " + std::to_string(fleet_.size()) + " (" + names + ")";
}

}  // namespace voxvis::server
