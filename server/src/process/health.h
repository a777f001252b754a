// health.h — the server's standard health service, grpc.health.v1.Health.
//
// Why not gRPC's default one (grpc::EnableDefaultHealthCheckService): in gRPC
// 1.51 its Shutdown() marks every name NOT_SERVING but leaves Watch streams
// open, so a single load balancer watching the server holds every graceful
// stop for the whole shutdown grace. This service answers the same way and
// ends its streams when the server stops:
//
//  * Check(name): the name's status; NOT_FOUND for a name never set.
//  * Watch(name): the current status at once (SERVICE_UNKNOWN for a name never
//    set; the stream stays open, the name may be set later), then each change.
//  * Shutdown(): every name NOT_SERVING, later changes ignored, and every
//    Watch stream is sent NOT_SERVING and ended with UNAVAILABLE "server is
//    shutting down" (the status the server's own streams end with).
//
// The name "" (the whole server) exists from the start, SERVING, as in the
// default service. Install it with both
//   builder.RegisterService(health.get());
//   builder.SetOption(std::make_unique<grpc::HealthCheckServiceServerBuilderOption>(std::move(health)));
// so that grpc::Server owns it and Server::GetHealthCheckService() returns it
// (the option also keeps gRPC from adding its default service).
//
// No token is needed: load balancers have none. A Watch stream holds at most
// one unsent status (a newer one replaces it), so a client that never reads
// costs a bounded amount of memory.
//
// Threads: every method may be called from any thread. Lock order: the
// service's mutex, then a stream's; gRPC's reactions on a stream take only the
// stream's, except OnDone, which takes only the service's.
#pragma once

#include <map>
#include <mutex>
#include <set>
#include <string>

#include <grpcpp/health_check_service_interface.h>

#include "grpc/health/v1/health.grpc.pb.h"

namespace voxvis::server {

class HealthService final : public grpc::HealthCheckServiceInterface,
                            public grpc::health::v1::Health::CallbackService {
 public:
  using ServingStatus = grpc::health::v1::HealthCheckResponse::ServingStatus;

  HealthService();
  HealthService(const HealthService&) = delete;
  HealthService& operator=(const HealthService&) = delete;

  // grpc::HealthCheckServiceInterface
  void SetServingStatus(const std::string& service_name, bool serving) override;
  /// Every name set so far.
  void SetServingStatus(bool serving) override;
  void Shutdown() override;

  // grpc.health.v1.Health
  grpc::ServerUnaryReactor* Check(grpc::CallbackServerContext* context,
                                  const grpc::health::v1::HealthCheckRequest* request,
                                  grpc::health::v1::HealthCheckResponse* response) override;
  grpc::ServerWriteReactor<grpc::health::v1::HealthCheckResponse>* Watch(
      grpc::CallbackServerContext* context, const grpc::health::v1::HealthCheckRequest* request) override;

 private:
  class WatchStream;

  /// Sends `status` to the streams watching `name`.
  void notify_locked(const std::string& name, ServingStatus status);
  /// Called by a stream when gRPC is done with it.
  void forget(WatchStream* stream);

  std::mutex mu_;
  std::map<std::string, ServingStatus> status_;  // Guarded by mu_.
  std::set<WatchStream*> streams_;               // Guarded by mu_.
  bool shut_down_ = false;                       // Guarded by mu_.
};

}  // namespace voxvis::server
