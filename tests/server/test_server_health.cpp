// The standard services of the real server: gRPC health checking
// (grpc.health.v1.Health) reports SERVING, and server reflection lists the
// Visibility service. Called by method name with hand-encoded protobuf
// bytes, since the tests do not have those services' generated code.
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "server_process.h"

namespace voxvis::servertest {
namespace {

std::string show(const grpc::Status& s) {
  return std::to_string(static_cast<int>(s.error_code())) + " " + s.error_message();
}

TEST(ServerHealth, HealthCheckAndReflection) {
  ServerProcess server;
  ASSERT_TRUE(server.start());
  const auto channel = server.channel();

  // HealthCheckRequest{service: ""} is empty; HealthCheckResponse{status:
  // SERVING} is field 1, varint 1.
  std::string response;
  grpc::Status s = generic_unary(channel, "/grpc.health.v1.Health/Check", "", &response);
  ASSERT_TRUE(s.ok()) << show(s);
  EXPECT_EQ(response, std::string("\x08\x01", 2));
  // An unknown service name: NOT_FOUND. (HealthCheckRequest{service: "nope"}
  // is field 1, length-delimited.)
  s = generic_unary(channel, "/grpc.health.v1.Health/Check", std::string("\x0a\x04nope", 6),
                    &response);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::NOT_FOUND) << show(s);

  // ServerReflectionRequest{list_services: "*"}: field 7, length-delimited.
  std::vector<std::string> answers;
  s = generic_bidi(channel, "/grpc.reflection.v1alpha.ServerReflection/ServerReflectionInfo",
                   std::string("\x3a\x01*", 3), &answers);
  ASSERT_TRUE(s.ok()) << show(s);
  ASSERT_EQ(answers.size(), 1u);
  EXPECT_NE(answers[0].find("voxvis.v1.Visibility"), std::string::npos) << answers[0];
  EXPECT_NE(answers[0].find("grpc.health.v1.Health"), std::string::npos) << answers[0];

  // Unknown methods are refused as such (the generic calls do reach a server
  // that checks names).
  s = generic_unary(channel, "/voxvis.v1.Visibility/NoSuchMethod", "", &response);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::UNIMPLEMENTED) << show(s);
  EXPECT_EQ(server.terminate(), 0);
}

}  // namespace
}  // namespace voxvis::servertest
