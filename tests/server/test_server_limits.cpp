// What a request may cost before anything refuses it: gRPC reads a whole
// message before checking its size, so one oversized request once added its
// full size (442 MB for 450 MB) to the server's memory, with or without a
// token. Now the buffer quota bounds it on every connection, and with TLS a
// call without a known token is refused on its headers, before its message is
// read. And calls in progress are capped server-wide.
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "server_process.h"

namespace voxvis::servertest {
namespace {

using ::testing::HasSubstr;

/// A CreateScene request of about `bytes` bytes (a scene_json that does not
/// parse; it never gets that far).
std::string big_create_request(std::size_t bytes) {
  v1::CreateSceneRequest req;
  req.set_scene_id("big");
  req.set_scene_json(std::string(bytes, ' '));
  return req.SerializeAsString();
}

TEST(ServerLimits, BufferQuotaBoundsAnOversizedRequest) {
  // 200 MB against a 64 MiB message limit and 80 MiB of gRPC buffers.
  ServerProcess server({"--grpc-memory-mib", "80"});
  ASSERT_TRUE(server.start());
  ASSERT_TRUE(server.api().create_scene_json("w", wall_scene_json()).ok());
  const long before = server.peak_rss_kib();
  ASSERT_GT(before, 0);
  std::string response;
  const grpc::Status s = generic_unary(server.channel(), "/voxvis.v1.Visibility/CreateScene",
                                       big_create_request(200u << 20), &response, Seconds(120));
  EXPECT_FALSE(s.ok());
  EXPECT_EQ(s.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << show(s);
  const long growth_mib = (server.peak_rss_kib() - before) / 1024;
  std::printf("peak RSS growth for a 200 MB request: %ld MiB\n", growth_mib);
  EXPECT_LT(growth_mib, 150) << "the request was buffered beyond the quota";
  // The server goes on serving.
  std::vector<std::string> ids;
  EXPECT_TRUE(server.api().list_scenes(&ids).ok());
  EXPECT_EQ(server.terminate(), 0);
}

TEST(ServerLimits, WithTlsUnauthenticatedCallsAreRefusedBeforeTheirMessageIsRead) {
  ServerProcess server;
  const std::string cert = server.path("cert.pem"), key = server.path("key.pem");
  ASSERT_TRUE(make_test_certificate(cert, key, server.dir()));
  const std::string tokens = server.path("tokens");
  spit(tokens, "admin admin-token-0123456789abcdef\nviewer viewer-token-0123456789abcdef\n");
  server.extra_args() = {"--tls-cert", cert, "--tls-key", key, "--tokens", tokens};
  ASSERT_TRUE(server.start());

  grpc::SslCredentialsOptions ssl;
  ssl.pem_root_certs = slurp(cert);
  grpc::ChannelArguments args;
  args.SetSslTargetNameOverride("voxvis.test");
  const auto tls_channel = [&] {
    return grpc::CreateCustomChannel(server.address(), grpc::SslCredentials(ssl), args);
  };

  const long before = server.peak_rss_kib();
  std::string response;
  grpc::Status s = generic_unary(tls_channel(), "/voxvis.v1.Visibility/CreateScene",
                                 big_create_request(60u << 20), &response, Seconds(120));
  EXPECT_EQ(s.error_code(), grpc::StatusCode::UNAUTHENTICATED) << show(s);
  EXPECT_THAT(s.error_message(), HasSubstr("missing bearer token"));
  const long growth_mib = (server.peak_rss_kib() - before) / 1024;
  std::printf("peak RSS growth for an unauthenticated 60 MB request over TLS: %ld MiB\n",
              growth_mib);
  EXPECT_LT(growth_mib, 20) << "the message was read before the token was checked";

  // A known token gets through to the handler, which checks its role.
  const Api viewer(tls_channel(), "viewer-token-0123456789abcdef");
  std::vector<std::string> ids;
  EXPECT_TRUE(viewer.list_scenes(&ids).ok());
  s = viewer.create_scene_json("x", wall_scene_json());
  EXPECT_EQ(s.error_code(), grpc::StatusCode::PERMISSION_DENIED) << show(s);
  const Api stranger(tls_channel(), "unknown-token-0123456789abcdef");
  s = stranger.list_scenes(&ids);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::UNAUTHENTICATED) << show(s);
  // Health needs no token.
  s = generic_unary(tls_channel(), "/grpc.health.v1.Health/Check", "", &response);
  EXPECT_TRUE(s.ok()) << show(s);
  EXPECT_EQ(server.terminate(), 0);
}

TEST(ServerLimits, CallsInProgressAreCapped) {
  ServerProcess server({"--max-calls", "3"});
  ASSERT_TRUE(server.start());
  const Api api = server.api();
  ASSERT_TRUE(api.create_scene_json("w", wall_scene_json()).ok());
  std::vector<std::unique_ptr<ViewStream>> open;
  // A unary call gives its place back just after its reply reaches the
  // client, so the scene's creation may still hold one for a moment: a stream
  // refused then is tried again.
  for (int i = 0; i < 3; ++i) {
    ASSERT_TRUE(wait_until(
        [&] {
          auto stream = std::make_unique<ViewStream>(api, "w");
          v1::ViewResponse r;
          if (!stream->frame(1, 0.0, wall_camera(), &r)) {
            stream->finish();
            return false;
          }
          open.push_back(std::move(stream));
          return true;
        },
        Seconds(10)))
        << "stream " << i;
  }
  v1::GetPvsResponse pvs;
  grpc::Status s = api.get_pvs("w", 0.0, wall_camera(), &pvs);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << show(s);
  EXPECT_THAT(s.error_message(), HasSubstr("server busy: 3 calls in progress (--max-calls)"));
  {
    ViewStream fourth(api, "w");
    v1::ViewResponse r;
    EXPECT_FALSE(fourth.frame(1, 0.0, wall_camera(), &r));
    s = fourth.finish();
    EXPECT_EQ(s.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << show(s);
  }
  // A place freed is a place taken again.
  EXPECT_TRUE(open.back()->finish().ok());
  open.pop_back();
  EXPECT_TRUE(wait_until([&] { return api.get_pvs("w", 0.0, wall_camera(), &pvs).ok(); },
                         Seconds(10)));
  for (auto& v : open) EXPECT_TRUE(v->finish().ok());
}

TEST(ServerLimits, BadLimitArgumentsAreStartErrors) {
  for (const std::vector<std::string>& args :
       {std::vector<std::string>{"--max-calls", "0"},
        std::vector<std::string>{"--max-streams-per-connection", "0"},
        std::vector<std::string>{"--grpc-memory-mib", "32"},  // Below 64 MiB messages.
        std::vector<std::string>{"--grpc-memory-mib", "nan"},
        std::vector<std::string>{"--max-view-lead", "-1"},
        std::vector<std::string>{"--max-time-step", "0"}}) {
    ServerProcess server(args);
    EXPECT_FALSE(server.start()) << args[0] << " " << args[1];
    EXPECT_THAT(server.log(), HasSubstr(args[0])) << server.log();
  }
}

}  // namespace
}  // namespace voxvis::servertest
