// TLS on the real server (--tls-cert, --tls-key) with the `voxvis` client
// (--tls-ca, --tls-server-name): a client that trusts the certificate gets
// through, with its bearer token; one that does not trust it, or speaks
// plaintext, or expects another name, is refused before any call is made.
#include <cstdlib>
#include <string>

#include <gtest/gtest.h>

#include "server_process.h"

namespace voxvis::servertest {
namespace {

TEST(ServerTls, OnlyClientsTrustingTheCertificateGetThrough) {
  ServerProcess server;
  const std::string cert = server.path("cert.pem"), key = server.path("key.pem");
  const std::string other = server.path("other.pem"), other_key = server.path("other-key.pem");
  // A self-signed certificate for "voxvis.test" (the client checks the name
  // it is told with --tls-server-name), and another one the server does not use.
  for (const auto& [c, k] : {std::pair{cert, key}, std::pair{other, other_key}}) {
    ASSERT_TRUE(make_test_certificate(c, k, server.dir()));
  }
  const std::string tokens = server.path("tokens");
  spit(tokens, "admin admin-token-0123456789abcdef\n");
  const std::string token_file = server.path("admin.token");
  spit(token_file, "admin-token-0123456789abcdef\n");
  server.extra_args() = {"--tls-cert", cert, "--tls-key", key, "--tokens", tokens};
  ASSERT_TRUE(server.start());

  const auto scenes = [&](std::vector<std::string> extra) {
    std::vector<std::string> argv = {VOXVIS_CLI, "scenes", "--server", server.address(),
                                     "--token-file", token_file};
    argv.insert(argv.end(), extra.begin(), extra.end());
    return run_program(argv, server.dir(), Seconds(60));
  };
  ProcessResult r = scenes({"--tls-ca", cert, "--tls-server-name", "voxvis.test"});
  EXPECT_EQ(r.status, 0) << r.err;

  r = scenes({"--tls-ca", other, "--tls-server-name", "voxvis.test"});  // Untrusted.
  EXPECT_EQ(r.status, 2) << r.out;
  EXPECT_NE(r.err.find("UNAVAILABLE"), std::string::npos) << r.err;

  r = scenes({"--tls-ca", cert, "--tls-server-name", "elsewhere.test"});  // Wrong name.
  EXPECT_EQ(r.status, 2) << r.out;

  r = scenes({});  // Plaintext to a TLS port.
  EXPECT_EQ(r.status, 2) << r.out;

  // The plaintext gRPC channel of the harness cannot reach it either.
  std::vector<std::string> ids;
  EXPECT_FALSE(server.api().list_scenes(&ids).ok());
  EXPECT_EQ(server.terminate(), 0);
}

TEST(ServerTls, KeyWithoutCertificateIsAStartError) {
  ServerProcess server;
  server.extra_args() = {"--tls-key", server.path("missing.pem")};
  EXPECT_FALSE(server.start());
  EXPECT_NE(server.log().find("--tls-cert and --tls-key go together"), std::string::npos)
      << server.log();
}

}  // namespace
}  // namespace voxvis::servertest
