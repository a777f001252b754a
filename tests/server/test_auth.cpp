// Tokens file parsing and the bearer-token check, down to the metadata
// lookup of a real (in-process) gRPC call.
#include <gtest/gtest.h>

#include <stdlib.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <future>
#include <string>

#include <grpcpp/generic/async_generic_service.h>
#include <grpcpp/generic/generic_stub.h>
#include <grpcpp/grpcpp.h>

#include "serving/auth.h"

namespace voxvis::server {
namespace {

const std::string kAdmin = "admin-token-0123456789";
const std::string kSim = "simulation-token-0123456789";
const std::string kViewer = "viewer-token-0123456789";

std::string good_file() {
  return "# voxvis tokens\n"
         "\n"
         "admin      " + kAdmin + "\n"
         "   # indented comment\n"
         "simulation\t" + kSim + "\r\n"
         "viewer " + kViewer;  // no final newline
}

TokenTable good_table() {
  TokenTable table;
  const Status s = table.parse(good_file(), "tokens.txt");
  EXPECT_TRUE(s.ok) << s.str();
  return table;
}

Status parse_error(const std::string& text) {
  TokenTable table;
  const Status s = table.parse(text, "t.txt");
  EXPECT_FALSE(s.ok);
  EXPECT_FALSE(table.enabled());
  return s;
}

TEST(Auth, RoleNames) {
  EXPECT_STREQ(role_name(Role::Viewer), "viewer");
  EXPECT_STREQ(role_name(Role::Simulation), "simulation");
  EXPECT_STREQ(role_name(Role::Admin), "admin");
}

TEST(Auth, DisabledAllowsEverything) {
  TokenTable table;
  EXPECT_FALSE(table.enabled());
  EXPECT_TRUE(table.authorize_header("", false, Role::Admin).ok());
  EXPECT_TRUE(table.authorize_header("Basic xyz", true, Role::Admin).ok());
}

TEST(Auth, GoodFileParses) {
  TokenTable table = good_table();
  EXPECT_TRUE(table.enabled());
  EXPECT_TRUE(table.authorize_header("Bearer " + kAdmin, true, Role::Admin).ok());
  EXPECT_TRUE(table.authorize_header("Bearer " + kSim, true, Role::Simulation).ok());
  EXPECT_TRUE(table.authorize_header("Bearer " + kViewer, true, Role::Viewer).ok());
}

TEST(Auth, RolesNest) {
  TokenTable table = good_table();
  auto code = [&](const std::string& token, Role need) {
    return table.authorize_header("Bearer " + token, true, need).error_code();
  };
  EXPECT_EQ(code(kAdmin, Role::Viewer), grpc::StatusCode::OK);
  EXPECT_EQ(code(kAdmin, Role::Simulation), grpc::StatusCode::OK);
  EXPECT_EQ(code(kAdmin, Role::Admin), grpc::StatusCode::OK);
  EXPECT_EQ(code(kSim, Role::Viewer), grpc::StatusCode::OK);
  EXPECT_EQ(code(kSim, Role::Simulation), grpc::StatusCode::OK);
  EXPECT_EQ(code(kSim, Role::Admin), grpc::StatusCode::PERMISSION_DENIED);
  EXPECT_EQ(code(kViewer, Role::Viewer), grpc::StatusCode::OK);
  EXPECT_EQ(code(kViewer, Role::Simulation), grpc::StatusCode::PERMISSION_DENIED);
  EXPECT_EQ(code(kViewer, Role::Admin), grpc::StatusCode::PERMISSION_DENIED);
}

TEST(Auth, PermissionDeniedNamesBothRoles) {
  TokenTable table = good_table();
  const grpc::Status s = table.authorize_header("Bearer " + kViewer, true, Role::Simulation);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::PERMISSION_DENIED);
  EXPECT_EQ(s.error_message(), "this call needs the simulation role; the token has viewer");
}

TEST(Auth, BadHeadersAreUnauthenticatedAndNeverEchoed) {
  TokenTable table = good_table();
  const std::string unknown = "not-a-known-token-42424242";
  for (const auto& [value, present] : std::vector<std::pair<std::string, bool>>{
           {"", false},
           {"", true},
           {"Bearer", true},
           {"Bearer ", true},
           {"Basic " + unknown, true},
           {"bearer" + unknown, true},
           {unknown, true},
           {"Bearer " + unknown, true},
           {"Bearer  " + kAdmin, true},       // two spaces: the token would start with one
           {"Bearer " + kAdmin + " ", true},  // trailing space is part of the token
           {"Bearer " + kAdmin.substr(0, kAdmin.size() - 1), true},  // a prefix
           {"Bearer " + kAdmin + "x", true},                         // an extension
       }) {
    const grpc::Status s = table.authorize_header(value, present, Role::Viewer);
    EXPECT_EQ(s.error_code(), grpc::StatusCode::UNAUTHENTICATED) << "'" << value << "'";
    EXPECT_EQ(s.error_message().find(unknown), std::string::npos) << s.error_message();
    EXPECT_EQ(s.error_message().find(kAdmin), std::string::npos) << s.error_message();
  }
  EXPECT_NE(table.authorize_header("", false, Role::Viewer).error_message().find("bearer token"),
            std::string::npos);
  EXPECT_EQ(table.authorize_header("Bearer " + unknown, true, Role::Viewer).error_message(),
            "unknown bearer token");
}

TEST(Auth, ErrorsNameTheLine) {
  const std::string ok_line = "viewer " + kViewer + "\n";
  Status s = parse_error(ok_line + "# c\nroot " + kAdmin + "\n");
  EXPECT_EQ(s.field, "t.txt:3");
  EXPECT_NE(s.message.find("unknown role 'root'"), std::string::npos) << s.str();

  s = parse_error(ok_line + "admin\n");
  EXPECT_EQ(s.field, "t.txt:2");
  EXPECT_NE(s.message.find("two fields"), std::string::npos) << s.str();

  s = parse_error(ok_line + "admin " + kAdmin + " extra\n");
  EXPECT_EQ(s.field, "t.txt:2");
  EXPECT_NE(s.message.find("3 fields"), std::string::npos) << s.str();

  s = parse_error(ok_line + "\n\nadmin " + kViewer + "\n");
  EXPECT_EQ(s.field, "t.txt:4");
  EXPECT_NE(s.message.find("duplicate"), std::string::npos) << s.str();
  EXPECT_EQ(s.str().find(kViewer), std::string::npos) << "a token must never be echoed";

  s = parse_error(ok_line + "admin short-token-15c\n");  // 15 characters
  EXPECT_EQ(s.field, "t.txt:2");
  EXPECT_NE(s.message.find("16 to 512"), std::string::npos) << s.str();

  s = parse_error("admin " + std::string(513, 'a') + "\n");
  EXPECT_EQ(s.field, "t.txt:1");

  s = parse_error("admin " + kAdmin + "\x7f\n");
  EXPECT_EQ(s.field, "t.txt:1");
  EXPECT_NE(s.message.find("printable"), std::string::npos) << s.str();

  s = parse_error("admin caf\xc3\xa9-token-0123456789\n");
  EXPECT_EQ(s.field, "t.txt:1");
}

TEST(Auth, TokenLengthBoundsAreInclusive) {
  TokenTable table;
  const std::string min(16, 'm'), max(512, 'M');
  ASSERT_TRUE(table.parse("viewer " + min + "\nadmin " + max + "\n", "t").ok);
  EXPECT_TRUE(table.authorize_header("Bearer " + min, true, Role::Viewer).ok());
  EXPECT_TRUE(table.authorize_header("Bearer " + max, true, Role::Admin).ok());
  // '#' is a token character, not the start of a trailing comment.
  ASSERT_TRUE(table.parse("viewer #" + min + "\n", "t").ok);
  EXPECT_TRUE(table.authorize_header("Bearer #" + min, true, Role::Viewer).ok());
}

TEST(Auth, EmptyFileIsAnError) {
  for (const std::string text : {"", "\n\n", "# only a comment\n   \n"}) {
    const Status s = parse_error(text);
    EXPECT_EQ(s.field, "t.txt");
    EXPECT_EQ(s.message, "no tokens");
  }
}

TEST(Auth, FailedParseLeavesTableUnchanged) {
  TokenTable table = good_table();
  EXPECT_FALSE(table.parse("viewer " + std::string(20, 'z') + "\nbogus\n", "t").ok);
  EXPECT_TRUE(table.authorize_header("Bearer " + kAdmin, true, Role::Admin).ok());
  EXPECT_EQ(table.authorize_header("Bearer " + std::string(20, 'z'), true, Role::Viewer).error_code(),
            grpc::StatusCode::UNAUTHENTICATED);
}

TEST(Auth, LoadReadsFileAndNamesPathInErrors) {
  std::string templ = (std::filesystem::temp_directory_path() / "voxvis_auth_XXXXXX").string();
  ASSERT_NE(::mkdtemp(templ.data()), nullptr);
  const std::filesystem::path dir = templ;
  const std::string path = (dir / "tokens").string();
  {
    std::ofstream(path) << good_file();
  }
  TokenTable table;
  Status s = table.load(path);
  ASSERT_TRUE(s.ok) << s.str();
  EXPECT_TRUE(table.enabled());
  EXPECT_TRUE(table.authorize_header("Bearer " + kSim, true, Role::Simulation).ok());

  {
    std::ofstream(path) << "viewer " << kViewer << "\nviewer " << kViewer << "\n";
  }
  TokenTable other;
  s = other.load(path);
  EXPECT_FALSE(s.ok);
  EXPECT_EQ(s.field, path + ":2");

  s = other.load((dir / "missing").string());
  EXPECT_FALSE(s.ok);
  EXPECT_EQ(s.field, (dir / "missing").string());
  EXPECT_FALSE(other.enabled());
  std::filesystem::remove_all(dir);
}

// authorize() on a real call: the metadata lookup, not just the header check.
class AuthService : public grpc::CallbackGenericService {
 public:
  explicit AuthService(const TokenTable& table) : table_(table) {}
  grpc::ServerGenericBidiReactor* CreateReactor(grpc::GenericCallbackServerContext* ctx) override {
    class Reactor : public grpc::ServerGenericBidiReactor {
     public:
      explicit Reactor(grpc::Status s) { Finish(std::move(s)); }
      void OnDone() override { delete this; }
    };
    return new Reactor(table_.authorize(ctx, Role::Simulation));
  }

 private:
  const TokenTable& table_;
};

TEST(Auth, AuthorizeReadsCallMetadata) {
  TokenTable table = good_table();
  AuthService service(table);
  int port = 0;
  grpc::ServerBuilder builder;
  builder.AddListeningPort("127.0.0.1:0", grpc::InsecureServerCredentials(), &port);
  builder.RegisterCallbackGenericService(&service);
  std::unique_ptr<grpc::Server> server = builder.BuildAndStart();
  ASSERT_TRUE(server);
  ASSERT_GT(port, 0);
  auto channel = grpc::CreateChannel("127.0.0.1:" + std::to_string(port),
                                     grpc::InsecureChannelCredentials());
  grpc::GenericStub stub(channel);

  auto call = [&](const std::vector<std::string>& authorization) {
    grpc::ClientContext context;
    for (const std::string& value : authorization) context.AddMetadata("authorization", value);
    // A default ByteBuffer holds no buffer at all, which gRPC rejects as a
    // message; an empty slice makes an empty message.
    grpc::Slice empty("");
    grpc::ByteBuffer request(&empty, 1), response;
    std::promise<grpc::Status> done;
    stub.UnaryCall(&context, "/test.Auth/Call", grpc::StubOptions(), &request, &response,
                   [&](grpc::Status s) { done.set_value(std::move(s)); });
    return done.get_future().get();
  };

  EXPECT_EQ(call({}).error_code(), grpc::StatusCode::UNAUTHENTICATED);
  EXPECT_EQ(call({"Bearer " + kSim}).error_code(), grpc::StatusCode::OK);
  EXPECT_EQ(call({"Bearer " + kAdmin}).error_code(), grpc::StatusCode::OK);
  const grpc::Status denied = call({"Bearer " + kViewer});
  EXPECT_EQ(denied.error_code(), grpc::StatusCode::PERMISSION_DENIED);
  EXPECT_EQ(denied.error_message(), "this call needs the simulation role; the token has viewer");
  EXPECT_EQ(call({"Basic " + kSim}).error_code(), grpc::StatusCode::UNAUTHENTICATED);
  EXPECT_EQ(call({"Bearer " + kSim, "Bearer " + kAdmin}).error_code(),
            grpc::StatusCode::UNAUTHENTICATED);
  server->Shutdown();
}

}  // namespace
}  // namespace voxvis::server
