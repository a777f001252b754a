#include "voxvis/fleet.h"

namespace voxvis::client {

std::unique_ptr<Fleet> Fleet::connect(std::string_view servers, const ConnectOptions& options, std::string* error) {
  std::unique_ptr<Fleet> fleet(new Fleet());
  std::string message;
  if (!routing::parse_servers(servers, &fleet->shards_, &message)) {
    *error = "servers: " + message;
    return nullptr;
  }
  // A channel per server, made now (cheap: gRPC connects at the first call),
  // so that a bad option shows here and at() cannot fail.
  for (const routing::Shard& shard : fleet->shards_) {
    ConnectOptions o = options;
    o.address = shard.address;
    std::shared_ptr<grpc::Channel> channel = client::connect(o, error);
    if (channel == nullptr) return nullptr;
    fleet->clients_.push_back(std::make_unique<Client>(std::move(channel), o.token, o.address));
  }
  return fleet;
}

}  // namespace voxvis::client
