// admission.h — which calls the server takes and how they end: the token's
// role, the limit on calls in progress, the registry of live streams, and
// shutdown (which ends every stream). Every call, unary or streaming, comes
// in through here; the scenes and their frames are Serving's (serving.h).
#pragma once

#include <atomic>
#include <cstdint>
#include <mutex>
#include <unordered_set>

#include <grpcpp/grpcpp.h>

#include "scenes/metrics.h"
#include "serving/auth.h"
#include "wire/calls.h"

namespace voxvis::server {

struct SceneEntry;

/// A stream the server can end from outside (shutdown, scene deletion).
class Stream {
 public:
  virtual ~Stream() = default;
  /// Ends the stream with `status` once its in-flight frame is answered, when
  /// `scene` is null or is the stream's scene.
  virtual void stop_if(const SceneEntry* scene, const grpc::Status& status) = 0;
};

class Admission {
 public:
  /// `max_calls`: calls in progress allowed, server-wide (--max-calls).
  Admission(const TokenTable& tokens, Metrics& metrics, int max_calls);
  Admission(const Admission&) = delete;
  Admission& operator=(const Admission&) = delete;

  /// OK when the call's token has `role`: else UNAUTHENTICATED or PERMISSION_DENIED.
  grpc::Status authorize(const grpc::CallbackServerContext* ctx, Role role) const {
    return tokens_.authorize(ctx, role);
  }
  /// Takes a place among the calls in progress: OK, or RESOURCE_EXHAUSTED
  /// when --max-calls are under way. Each OK is paired with a leave_call().
  grpc::Status enter_call();
  void leave_call() { calls_.fetch_sub(1, std::memory_order_relaxed); }

  /// Starts a raw unary call: checks the token's role, takes a place among
  /// the calls in progress and parses the request. Null after answering the
  /// call (UNAUTHENTICATED, PERMISSION_DENIED, RESOURCE_EXHAUSTED, or
  /// INVALID_ARGUMENT when the bytes are not a Req); `*reactor` is the
  /// call's reactor either way.
  template <class Req, class Resp>
  TypedUnaryCall<Req, Resp>* start_unary(const char* method, grpc::CallbackServerContext* ctx, Role role,
                                         const grpc::ByteBuffer* in, grpc::ByteBuffer* out,
                                         grpc::ServerUnaryReactor** reactor);
  /// Ends a unary call, counting an error.
  void finish_unary(UnaryCall* r, const char* method, const grpc::Status& s);

  /// Registers a live stream; false when the server is shutting down.
  bool add_stream(Stream* s);
  void remove_stream(Stream* s);
  /// Ends every stream on scene `e` with `status` (the scene is being deleted).
  void stop_streams(const SceneEntry& e, const grpc::Status& status);
  /// Ends every stream with UNAVAILABLE after its in-flight frame and refuses
  /// new ones. Call before grpc::Server::Shutdown.
  void begin_shutdown();
  /// True from begin_shutdown on: queued work is answered without running.
  bool shutting_down() const { return stopping_.load(std::memory_order_relaxed); }
  /// The same flag, for those that only read it (SceneRegistry's builds).
  const std::atomic<bool>& stopping() const { return stopping_; }

  /// Counts a queued request answered without running: its client had gone
  /// or the server was stopping.
  void count_dropped() { dropped_.fetch_add(1, std::memory_order_relaxed); }
  std::uint64_t dropped() const { return dropped_.load(std::memory_order_relaxed); }
  /// Counts a call ended with a non-OK status.
  void count_error(const char* method, const grpc::Status& status) { metrics_.error(method, status.error_code()); }

 private:
  const TokenTable& tokens_;
  Metrics& metrics_;
  const int max_calls_;
  std::atomic<int> calls_{0};
  std::atomic<std::uint64_t> dropped_{0};
  std::atomic<bool> stopping_{false};  // shutting_down_, readable without the lock.

  std::mutex streams_mu_;
  std::unordered_set<Stream*> streams_;  // Guarded by streams_mu_.
  bool shutting_down_ = false;           // Guarded by streams_mu_.
};

template <class Req, class Resp>
TypedUnaryCall<Req, Resp>* Admission::start_unary(const char* method, grpc::CallbackServerContext* ctx, Role role,
                                                  const grpc::ByteBuffer* in, grpc::ByteBuffer* out,
                                                  grpc::ServerUnaryReactor** reactor) {
  auto* call = new TypedUnaryCall<Req, Resp>(out);
  *reactor = call;
  if (grpc::Status denied = authorize(ctx, role); !denied.ok()) {
    finish_unary(call, method, denied);
    return nullptr;
  }
  if (grpc::Status busy = enter_call(); !busy.ok()) {
    finish_unary(call, method, busy);
    return nullptr;
  }
  call->on_end([this] { leave_call(); });
  if (parse_message(*in, &call->req)) return call;
  finish_unary(call, method, malformed(Req::descriptor()->full_name(), in->Length()));
  return nullptr;
}

}  // namespace voxvis::server
