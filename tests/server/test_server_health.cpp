// The standard services of the real server: gRPC health checking
// (grpc.health.v1.Health: Check, and Watch streams that end at once when the
// server stops), and server reflection, which is off unless --reflection is
// given. Called by method name with hand-encoded protobuf bytes, since the
// tests do not have those services' generated code.
#include <chrono>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include <grpcpp/generic/generic_stub.h>
#include <gtest/gtest.h>

#include "server_process.h"

namespace voxvis::servertest {
namespace {

const char* const kCheck = "/grpc.health.v1.Health/Check";
const char* const kWatch = "/grpc.health.v1.Health/Watch";
const char* const kReflection = "/grpc.reflection.v1alpha.ServerReflection/ServerReflectionInfo";
// HealthCheckResponse{status}: field 1, varint.
const std::string kServing("\x08\x01", 2);
const std::string kNotServing("\x08\x02", 2);
const std::string kServiceUnknown("\x08\x03", 2);
// ServerReflectionRequest{list_services: "*"}: field 7, length-delimited.
const std::string kListServices("\x3a\x01*", 3);

/// HealthCheckRequest{service: name}: field 1, length-delimited (names
/// shorter than 128 bytes, so the length is one byte).
std::string health_request(const std::string& name) {
  if (name.empty()) return {};
  return std::string(1, '\x0a') + static_cast<char>(name.size()) + name;
}

std::string bytes_of(const grpc::ByteBuffer& buffer) {
  std::vector<grpc::Slice> slices;
  std::string bytes;
  if (buffer.Dump(&slices).ok())
    for (const grpc::Slice& s : slices) bytes.append(reinterpret_cast<const char*>(s.begin()), s.size());
  return bytes;
}

/// One grpc.health.v1.Health/Watch call (gRPC's callback client API): every
/// HealthCheckResponse is kept, as bytes, and the final status.
class WatchCall final : public grpc::ClientBidiReactor<grpc::ByteBuffer, grpc::ByteBuffer> {
 public:
  WatchCall(const std::shared_ptr<grpc::Channel>& channel, const std::string& name)
      : stub_(channel) {
    context_.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(60));
    grpc::Slice slice(health_request(name));
    request_ = grpc::ByteBuffer(&slice, 1);
    stub_.PrepareBidiStreamingCall(&context_, kWatch, grpc::StubOptions(), this);
    StartWriteLast(&request_, grpc::WriteOptions());
    StartRead(&response_);
    StartCall();
  }
  ~WatchCall() override {
    context_.TryCancel();
    wait_done(Seconds(30));
  }
  WatchCall(const WatchCall&) = delete;
  WatchCall& operator=(const WatchCall&) = delete;

  void OnReadDone(bool ok) override {
    if (!ok) return;
    {
      std::lock_guard<std::mutex> lock(mu_);
      messages_.push_back(bytes_of(response_));
    }
    cv_.notify_all();
    StartRead(&response_);
  }
  void OnDone(const grpc::Status& status) override {
    std::lock_guard<std::mutex> lock(mu_);
    status_ = status;
    done_ = true;
    cv_.notify_all();
  }

  /// Waits until `count` messages have arrived or the call ended.
  bool wait_messages(std::size_t count, Seconds timeout) {
    std::unique_lock<std::mutex> lock(mu_);
    return cv_.wait_for(lock, timeout, [&] { return messages_.size() >= count || done_; }) &&
           messages_.size() >= count;
  }
  bool wait_done(Seconds timeout) {
    std::unique_lock<std::mutex> lock(mu_);
    return cv_.wait_for(lock, timeout, [&] { return done_; });
  }
  std::vector<std::string> messages() const {
    std::lock_guard<std::mutex> lock(mu_);
    return messages_;
  }
  grpc::Status status() const {
    std::lock_guard<std::mutex> lock(mu_);
    return status_;
  }

 private:
  grpc::GenericStub stub_;
  grpc::ClientContext context_;
  grpc::ByteBuffer request_, response_;
  mutable std::mutex mu_;
  std::condition_variable cv_;
  std::vector<std::string> messages_;  // Guarded by mu_.
  grpc::Status status_;                // Guarded by mu_.
  bool done_ = false;                  // Guarded by mu_.
};

/// ServerReflectionInfo with one list_services request, sending `token`
/// (when not empty) as "authorization: Bearer <token>": the call's status
/// and every answer.
grpc::Status list_services(const std::shared_ptr<grpc::Channel>& channel, const std::string& token,
                           std::vector<std::string>* answers) {
  grpc::GenericStub stub(channel);
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(10));
  if (!token.empty()) context.AddMetadata("authorization", "Bearer " + token);
  grpc::CompletionQueue cq;
  grpc::Status status(grpc::StatusCode::UNKNOWN, "no completion");
  void* tag = nullptr;
  bool ok = false;
  {
    std::unique_ptr<grpc::GenericClientAsyncReaderWriter> call = stub.PrepareCall(&context, kReflection, &cq);
    int step = 0, finish = 0;
    const auto next = [&] { return cq.Next(&tag, &ok) && tag == &step && ok; };
    call->StartCall(&step);
    if (next()) {
      grpc::Slice slice(kListServices);
      call->Write(grpc::ByteBuffer(&slice, 1), &step);
      if (next()) {
        call->WritesDone(&step);
        if (next()) {
          grpc::ByteBuffer buffer;
          for (;;) {
            call->Read(&buffer, &step);
            if (!next()) break;
            answers->push_back(bytes_of(buffer));
          }
        }
      }
    }
    call->Finish(&status, &finish);
    while (cq.Next(&tag, &ok) && tag != &finish) {
    }
  }
  cq.Shutdown();
  while (cq.Next(&tag, &ok)) {
  }
  return status;
}

TEST(ServerHealth, CheckAnswersForTheServerAndTheVisibilityService) {
  ServerProcess server;
  ASSERT_TRUE(server.start());
  const auto channel = server.channel();

  std::string response;
  grpc::Status s = generic_unary(channel, kCheck, health_request(""), &response);
  ASSERT_TRUE(s.ok()) << show(s);
  EXPECT_EQ(response, kServing);
  s = generic_unary(channel, kCheck, health_request("voxvis.v1.Visibility"), &response);
  ASSERT_TRUE(s.ok()) << show(s);
  EXPECT_EQ(response, kServing);
  s = generic_unary(channel, kCheck, health_request("nope"), &response);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::NOT_FOUND) << show(s);

  // Unknown methods are refused as such (the generic calls do reach a server
  // that checks names).
  s = generic_unary(channel, "/voxvis.v1.Visibility/NoSuchMethod", "", &response);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::UNIMPLEMENTED) << show(s);
  EXPECT_EQ(server.terminate(), 0);
}

TEST(ServerHealth, WatchOfAnUnknownNameStaysOpen) {
  ServerProcess server;
  ASSERT_TRUE(server.start());
  const auto channel = server.channel();

  // An unknown name is reported as such, and the stream stays open (the name
  // may be registered later).
  WatchCall unknown(channel, "nope");
  ASSERT_TRUE(unknown.wait_messages(1, Seconds(10)));
  EXPECT_EQ(unknown.messages()[0], kServiceUnknown);
  WatchCall watch(channel, "voxvis.v1.Visibility");
  ASSERT_TRUE(watch.wait_messages(1, Seconds(10)));
  EXPECT_EQ(watch.messages()[0], kServing);
  EXPECT_FALSE(unknown.wait_done(Seconds(0.2))) << show(unknown.status());
  EXPECT_EQ(server.terminate(), 0);
  ASSERT_TRUE(unknown.wait_done(Seconds(10)));
  EXPECT_EQ(unknown.messages(), (std::vector<std::string>{kServiceUnknown, kNotServing}));
  EXPECT_EQ(unknown.status().error_code(), grpc::StatusCode::UNAVAILABLE) << show(unknown.status());
}

TEST(ServerHealth, ShutdownEndsOpenWatchStreams) {
  ServerProcess server;
  ASSERT_TRUE(server.start());
  WatchCall all(server.channel(), "");
  WatchCall visibility(server.channel(), "voxvis.v1.Visibility");
  ASSERT_TRUE(all.wait_messages(1, Seconds(10)));
  ASSERT_TRUE(visibility.wait_messages(1, Seconds(10)));

  // The health service ends its streams itself when the server stops, with
  // the server's shutdown status, rather than leaving them open for gRPC to
  // cut when the shutdown grace (5 s) runs out. The exit is therefore not
  // held up by a load balancer's Watch.
  EXPECT_EQ(server.terminate(), 0);
  for (WatchCall* w : {&all, &visibility}) {
    ASSERT_TRUE(w->wait_done(Seconds(10)));
    EXPECT_EQ(w->messages(), (std::vector<std::string>{kServing, kNotServing}));
    EXPECT_EQ(w->status().error_code(), grpc::StatusCode::UNAVAILABLE) << show(w->status());
    EXPECT_EQ(w->status().error_message(), "server is shutting down");
  }
}

TEST(ServerHealth, HealthCommandSaysWhetherTheServerServes) {
  // `voxvis health`: the container health check and the operator's probe.
  ServerProcess server;
  ASSERT_TRUE(server.start());
  ProcessResult r = run_program({VOXVIS_CLI, "health", "--server", server.address()}, server.dir());
  EXPECT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(r.out, "SERVING\n");
  r = run_program({VOXVIS_CLI, "health", "--server", server.address(), "--service", "voxvis.v1.Visibility"},
                  server.dir());
  EXPECT_EQ(r.status, 0) << r.err;
  r = run_program({VOXVIS_CLI, "health", "--server", server.address(), "--service", "no.such.Service"},
                  server.dir());
  EXPECT_EQ(r.status, 4);
  EXPECT_NE(r.err.find("service 'no.such.Service' at " + server.address() + ": unknown"), std::string::npos)
      << r.err;
  r = run_program({VOXVIS_CLI, "health", "--server", server.address(), "--timeout", "0"}, server.dir());
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("--timeout"), std::string::npos) << r.err;

  // Stopped: no answer within the timeout, exit 4 (not a hang).
  const std::string address = server.address();
  EXPECT_EQ(server.terminate(), 0);
  const auto start = std::chrono::steady_clock::now();
  r = run_program({VOXVIS_CLI, "health", "--server", address, "--timeout", "1"}, server.dir(), Seconds(20));
  EXPECT_EQ(r.status, 4) << r.err;
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(15));
  EXPECT_NE(r.err.find("no health answer from " + address + " within 1 s"), std::string::npos) << r.err;
}

TEST(ServerReflection, OffByDefault) {
  {
    ServerProcess server;
    ASSERT_TRUE(server.start());
    std::vector<std::string> answers;
    const grpc::Status s = list_services(server.channel(), "", &answers);
    EXPECT_EQ(s.error_code(), grpc::StatusCode::UNIMPLEMENTED) << show(s);
    EXPECT_TRUE(answers.empty());
    EXPECT_EQ(server.terminate(), 0);
  }
  // With tokens: reflection would answer without one, so it is not there at
  // all, for calls with a token or without.
  ServerProcess server;
  const std::string token = "0123456789abcdef0123456789abcdef";
  spit(server.path("tokens"), "admin " + token + "\n");
  server.extra_args() = {"--tokens", server.path("tokens")};
  ASSERT_TRUE(server.start());
  for (const std::string& t : {std::string(), token}) {
    std::vector<std::string> answers;
    const grpc::Status s = list_services(server.channel(), t, &answers);
    EXPECT_EQ(s.error_code(), grpc::StatusCode::UNIMPLEMENTED)
        << (t.empty() ? "without" : "with") << " a token: " << show(s);
    EXPECT_TRUE(answers.empty());
  }
  EXPECT_EQ(server.terminate(), 0);
}

TEST(ServerReflection, ListsTheServicesWithTheFlag) {
  ServerProcess server({"--reflection"});
  ASSERT_TRUE(server.start());
  std::vector<std::string> answers;
  const grpc::Status s = list_services(server.channel(), "", &answers);
  ASSERT_TRUE(s.ok()) << show(s);
  ASSERT_EQ(answers.size(), 1u);
  EXPECT_NE(answers[0].find("voxvis.v1.Visibility"), std::string::npos) << answers[0];
  EXPECT_NE(answers[0].find("grpc.health.v1.Health"), std::string::npos) << answers[0];
  EXPECT_EQ(server.terminate(), 0);
}

}  // namespace
}  // namespace voxvis::servertest
