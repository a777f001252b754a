// calls.h — what every call of the Visibility service shares: the statuses it
// answers with, and the raw-message plumbing.
//
// The service registers every method raw (grpc::ByteBuffer in and out) and
// parses requests itself. With generated typed methods, gRPC 1.51 answers a
// request that does not parse with UNIMPLEMENTED and an empty message (unary)
// or ends the stream with OK as if the client had half-closed (streams); the
// service could neither say what was wrong nor count it. Here such a request
// gets INVALID_ARGUMENT "request: not a valid voxvis.v1.X (N bytes)".
//
// Every INVALID_ARGUMENT carries structured details: the trailer
// grpc-status-details-bin holds a google.rpc.Status with one BadRequest field
// violation (voxvis.v1.ErrorStatus and BadRequest, wire-compatible).
#pragma once

#include <atomic>
#include <cstdint>
#include <algorithm>
#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include <google/protobuf/arena.h>
#include <grpcpp/grpcpp.h>

#include "voxvis/types.h"

namespace voxvis::server {

/// INVALID_ARGUMENT: "field: message" as text, and a BadRequest naming the
/// field in the details.
grpc::Status invalid(const Status& s);
/// INVALID_ARGUMENT for bytes that are not a `type` message.
grpc::Status malformed(const std::string& type, std::size_t bytes);
/// Scene ids: 1-64 characters from [A-Za-z0-9._-], not starting with '.'
/// (the store's file names, too).
bool valid_scene_id(std::string_view id);
/// A request's scene id, checked before any message could echo it.
grpc::Status check_scene_id(const std::string& id);
/// NOT_FOUND for a (valid, hence short) scene id.
grpc::Status no_scene(const std::string& id);
/// NOT_FOUND for a scene deleted while the call was under way.
grpc::Status deleted(const std::string& scene_id);
grpc::Status shutting_down_status();

/// Parses a raw request; false when the bytes are not a message of its type.
bool parse_message(const grpc::ByteBuffer& in, google::protobuf::MessageLite* out);
/// Serializes a response into `out`.
grpc::Status serialize_message(const google::protobuf::MessageLite& m, grpc::ByteBuffer* out);

/// A message on an arena that is emptied, not freed, between uses. Clear()
/// of a message on no arena deletes its sub-messages (a camera and its
/// vectors, an answer's id sets and stats), so a stream reusing one plain
/// message still allocated several times an answer. fresh() drops the
/// previous message wholesale and returns a new one on the arena's first
/// block, which grows (on the next fresh()) to twice the most a message used,
/// up to 4 MiB: a stream's steady traffic allocates nothing (a message beyond
/// that takes further blocks from the heap, freed by the next fresh()). Call
/// fresh() on the thread that then fills the message: the arena's first
/// block serves that thread.
template <class M>
class ReusedMessage {
 public:
  ReusedMessage() { make(kFirstBlock); }
  ReusedMessage(const ReusedMessage&) = delete;
  ReusedMessage& operator=(const ReusedMessage&) = delete;

  M& get() { return *message_; }
  const M& get() const { return *message_; }
  M& fresh() {
    const std::uint64_t used = arena_->SpaceAllocated();
    if (used > block_size_ && block_size_ < kMostBlock) {
      make(static_cast<std::size_t>(std::min<std::uint64_t>(2 * used, kMostBlock)));
    } else {
      arena_->Reset();
      message_ = google::protobuf::Arena::CreateMessage<M>(arena_.get());
    }
    return *message_;
  }

 private:
  static constexpr std::size_t kFirstBlock = 2048;
  static constexpr std::size_t kMostBlock = std::size_t{4} << 20;
  void make(std::size_t bytes) {
    message_ = nullptr;
    arena_.reset();
    block_ = std::make_unique_for_overwrite<char[]>(bytes);
    block_size_ = bytes;
    arena_ = std::make_unique<google::protobuf::Arena>(block_.get(), bytes);
    message_ = google::protobuf::Arena::CreateMessage<M>(arena_.get());
  }
  std::unique_ptr<char[]> block_;  // Outlives arena_ (declared first).
  std::size_t block_size_ = 0;
  std::unique_ptr<google::protobuf::Arena> arena_;
  M* message_ = nullptr;
};

/// A unary call's reactor. finish() serializes the response when the status
/// is OK; the reactor deletes itself when gRPC is done with it.
class UnaryCall : public grpc::ServerUnaryReactor {
 public:
  virtual void finish(const grpc::Status& status) = 0;
  /// Runs `f` once, when the call is cancelled (its client gone, its deadline
  /// passed) or when gRPC is done with it, whichever comes first: a call
  /// nobody waits for stops counting then, even while its job is queued.
  void on_end(std::function<void()> f) { on_end_ = std::move(f); }
  void OnCancel() override { end(); }
  void OnDone() override {
    end();
    delete this;
  }

 private:
  void end() {
    if (on_end_ && !ended_.exchange(true)) on_end_();
  }
  std::function<void()> on_end_;  // Set before the call is handed to gRPC.
  std::atomic<bool> ended_{false};
};

template <class Req, class Resp>
class TypedUnaryCall final : public UnaryCall {
 public:
  explicit TypedUnaryCall(grpc::ByteBuffer* out) : out_(out) {}
  Req req;
  Resp resp;
  void finish(const grpc::Status& status) override {
    Finish(status.ok() ? serialize_message(resp, out_) : status);
  }

 private:
  grpc::ByteBuffer* out_;
};

}  // namespace voxvis::server
