// health_cmd.cpp — `voxvis health`: asks a server's standard health service
// (grpc.health.v1.Health/Check, no token needed) whether it serves, for
// container health checks, scripts and operators. Kubernetes probes the same
// service natively (deploy/k8s/); this is the same question from a shell.
#include <chrono>
#include <cstdio>
#include <memory>
#include <string>

#include <CLI/CLI.hpp>
#include <grpcpp/grpcpp.h>

#include "cli.h"
#include "common.h"
#include "grpc/health/v1/health.grpc.pb.h"
#include "options.h"
#include "voxvis/client.h"

namespace voxvis::cli {

int run_health(const HealthArgs& args) {
  if (!(args.timeout > 0.0 && args.timeout <= 3600.0)) {
    return report(FormatError{"", 0, "--timeout", "must be a number of seconds in (0, 3600]"});
  }
  client::ConnectOptions options;
  options.address = args.net.server;
  options.tls_ca_file = args.net.tls_ca;
  options.tls_server_name = args.net.tls_server_name;
  std::string error;
  const std::shared_ptr<grpc::Channel> channel = client::connect(options, &error);
  if (channel == nullptr) return report_message(error);

  const auto stub = grpc::health::v1::Health::NewStub(channel);
  grpc::ClientContext context;
  // Waits for the connection within the timeout: a server that is still
  // starting is given the time the caller allows, not refused at once.
  context.set_wait_for_ready(true);
  context.set_deadline(std::chrono::system_clock::now() +
                       std::chrono::microseconds(static_cast<long long>(args.timeout * 1e6)));
  grpc::health::v1::HealthCheckRequest request;
  request.set_service(args.service);
  grpc::health::v1::HealthCheckResponse response;
  const grpc::Status st = stub->Check(&context, request, &response);
  const std::string what = args.service.empty() ? "server" : "service '" + args.service + "'";
  if (!st.ok()) {
    if (st.error_code() == grpc::StatusCode::DEADLINE_EXCEEDED) {
      std::fprintf(stderr, "voxvis: error: no health answer from %s within %g s\n", args.net.server.c_str(),
                   args.timeout);
      return kExitNotServing;
    }
    if (st.error_code() == grpc::StatusCode::NOT_FOUND) {
      std::fprintf(stderr, "voxvis: error: %s at %s: unknown to its health service\n", what.c_str(),
                   args.net.server.c_str());
      return kExitNotServing;
    }
    report_status(st, args.net.server, "");
    return kExitNotServing;
  }
  const std::string status = grpc::health::v1::HealthCheckResponse::ServingStatus_Name(response.status());
  std::printf("%s\n", status.c_str());
  return response.status() == grpc::health::v1::HealthCheckResponse::SERVING ? kExitOk : kExitNotServing;
}

Command add_health_command(CLI::App& app) {
  auto args = std::make_shared<HealthArgs>();
  CLI::App* cmd = app.add_subcommand("health", "Ask a server's health service (grpc.health.v1) whether it serves.");
  add_net_options(cmd, &args->net, false);
  cmd->add_option("--service", args->service, "Health service name; default: the whole server")
      ->type_name("NAME");
  cmd->add_option("--timeout", args->timeout, "Seconds to wait for the connection and the answer")
      ->capture_default_str()
      ->type_name("SECONDS");
  cmd->footer(
      "Prints the status (SERVING, NOT_SERVING, ...). Exit status: 0 SERVING, 4 not\n"
      "serving, unknown, unreachable or no answer within the timeout, 2 bad arguments.\n"
      "No token is needed. For container health checks and scripts; Kubernetes asks\n"
      "the same service with its native gRPC probes.");
  return {cmd, [args] { return run_health(*args); }};
}

}  // namespace voxvis::cli
