// voxvis/client.h — a C++ client of voxvis-server (proto/voxvis/v1/voxvis.proto).
//
// Design choices:
//  * Synchronous and lock-step: ViewerSession and SimulationSession send one
//    message and wait for its answer, which is what a renderer or a simulation
//    that works frame by frame needs, and what lets `voxvis view` reproduce
//    `voxvis replay` line for line. Many concurrent streams (load generation)
//    use gRPC's callback API directly instead (client/loadgen_cmd.cpp).
//  * Sessions reassemble the server's incremental encodings (PVS deltas, wake
//    list changes) and check them: an inconsistent update is a protocol error,
//    never silently patched.
//  * Errors leave as grpc::Status; describe() turns one into a message. Calls
//    never wait for the channel to become ready (wait-for-ready off), so an
//    unreachable server fails at once with UNAVAILABLE.
//  * Tokens are read from files, never taken from the command line, where
//    every user of the machine could read them in the process list.
//
// Thread-safety: connect() and the free functions are thread-safe. A Client
// may be shared between threads (its unary calls are independent); a session
// must be used by one thread at a time.
#pragma once

#include <chrono>
#include <cstdint>
#include <memory>
#include <string>
#include <unordered_map>
#include <vector>

#include <grpcpp/grpcpp.h>

#include "voxvis/scene.h"
#include "voxvis/types.h"
#include "voxvis/v1/voxvis.grpc.pb.h"
#include "voxvis/v1/voxvis.pb.h"

namespace voxvis::client {

// ---------------------------------------------------------------------------
// Connection

struct ConnectOptions {
  std::string address;          ///< "host:port", e.g. "127.0.0.1:50051".
  std::string token;            ///< Bearer token; empty: none.
  std::string tls_ca_file;      ///< PEM root certificates; non-empty enables TLS.
  std::string tls_server_name;  ///< Name checked against the server's certificate
                                ///< instead of the host of `address`; TLS only.
  int max_message_bytes = 64 << 20;  ///< Largest message sent or received, bytes.
  /// Distinct values force distinct connections (gRPC otherwise shares one
  /// TCP connection between channels with equal arguments).
  int channel_index = 0;
};

/// Creates a channel (does not connect yet: the first call does). On error
/// (empty address, unreadable CA file, TLS options without a CA file) returns
/// nullptr and sets `error`.
std::shared_ptr<grpc::Channel> connect(const ConnectOptions& options, std::string* error);

/// Reads a whole file; on error sets `error` to "cannot open: <reason>" or
/// "cannot read: <reason>" (without the path).
bool read_whole(const std::string& path, std::string* text, std::string* error);

/// Reads a token file: the first line that is neither empty nor a comment
/// ('#' first after leading blanks), trimmed. The token must be printable
/// ASCII without white space. On error returns false and sets `error`
/// ("<path>: ...").
bool load_token(const std::string& path, std::string* token, std::string* error);

/// Adds "authorization: Bearer <token>" to `context`; nothing when `token` is empty.
void add_token(grpc::ClientContext* context, const std::string& token);

/// "INVALID_ARGUMENT", "UNAVAILABLE", ...
const char* status_code_name(grpc::StatusCode code);

/// "server: CODE: message" ("cannot reach server at ADDR: message" for
/// UNAVAILABLE when `address` is not empty).
std::string describe(const grpc::Status& status, const std::string& address = {});

// ---------------------------------------------------------------------------
// Conversions between engine values and wire messages. Ids, coordinates and
// times are copied unchanged (world units, seconds, degrees).

void to_proto(const Vec3& v, v1::Vec3* out);
Vec3 from_proto(const v1::Vec3& v);
void to_proto(const Quat& q, v1::Quat* out);
Quat from_proto(const v1::Quat& q);
/// A mesh as the flat arrays of the wire (x, y, z of each vertex in turn;
/// i, j, k of each triangle in turn).
void to_proto(const Mesh& mesh, v1::Mesh* out);
/// A scene; its meshes go once each into `meshes`, in the order objects
/// first name them, and the objects that share one (one shared_ptr) name
/// one entry (instancing). Doubles are copied bit for bit.
void to_proto(const SceneDesc& scene, v1::SceneDescription* out);
/// A move; its rotation is sent when has_rotation is set (a mesh's), else
/// left absent (the mesh keeps its rotation).
void to_proto(const Move& move, v1::Move* out);
/// A move as received, unchecked (the server's conversion checks).
Move from_proto(const v1::Move& move);
void to_proto(const Camera& camera, v1::Camera* out);
Camera from_proto(const v1::Camera& camera);
FrameStats from_proto(const v1::FrameStats& stats);

// ---------------------------------------------------------------------------
// Unary calls

/// A channel plus the token and deadlines every call uses.
class Client {
 public:
  /// `address` only names the server in messages.
  Client(std::shared_ptr<grpc::Channel> channel, std::string token, std::string address);

  /// Deadlines of the unary calls (streams have none). A create builds the
  /// scene before it answers, and a large mesh level's build takes minutes
  /// (docs/performance.md, "Creating scenes"): creates wait up to 5 minutes.
  std::chrono::milliseconds create_timeout{300'000};
  std::chrono::milliseconds call_timeout{10'000};

  /// CreateScene from a voxvis-scene/1 document (the server names its lines).
  grpc::Status create_scene(const std::string& scene_id, const std::string& scene_json,
                            v1::SceneInfo* info) const;
  /// CreateScene from a description.
  grpc::Status create_scene(const std::string& scene_id, const SceneDesc& scene,
                            v1::SceneInfo* info) const;
  /// CreateScene from a voxvis-scene/1 document, starting from `positions`
  /// (another server's ExportScene answer; none when null).
  grpc::Status create_scene(const std::string& scene_id, const std::string& scene_json,
                            const v1::ScenePositions* positions, v1::SceneInfo* info) const;
  /// DeleteScene; with `only_if_misplaced`, only a scene the server keeps
  /// unserved for another shard (the end of a move: FAILED_PRECONDITION,
  /// and kept, when the server serves it).
  grpc::Status delete_scene(const std::string& scene_id, bool only_if_misplaced = false) const;
  /// Ascending scene ids.
  grpc::Status list_scenes(std::vector<v1::SceneInfo>* scenes) const;
  /// The whole answer: the scenes served, and those kept for another shard.
  grpc::Status list_scenes(v1::ListScenesResponse* response) const;
  /// A scene's file and positions, to move it (ExportScene; admin). With
  /// `only_if_misplaced`, only a scene the server keeps unserved for another
  /// shard (FAILED_PRECONDITION when it serves it: it may still acknowledge
  /// moves the export would not carry).
  grpc::Status export_scene(const std::string& scene_id, v1::ExportSceneResponse* response,
                            bool only_if_misplaced = false) const;
  grpc::Status get_scene_stats(const std::string& scene_id, v1::SceneInfo* info) const;
  /// One PVS for a fresh viewer at time `t` (seconds). `result->wake` stays
  /// empty (GetPvs has none); `*t_used` (may be null) receives the scene time
  /// the frame was computed at.
  grpc::Status get_pvs(const std::string& scene_id, double t, const Camera& camera,
                       FrameResult* result, double* t_used = nullptr) const;

  /// Sets the token, wait-for-ready off, and a deadline `timeout` from now
  /// (none when zero) on a context for a call of this client.
  void prepare(grpc::ClientContext* context, std::chrono::milliseconds timeout) const;

  v1::Visibility::Stub& stub() const { return *stub_; }
  const std::shared_ptr<grpc::Channel>& channel() const { return channel_; }
  const std::string& address() const { return address_; }
  const std::string& token() const { return token_; }

 private:
  std::shared_ptr<grpc::Channel> channel_;
  std::unique_ptr<v1::Visibility::Stub> stub_;
  std::string token_;
  std::string address_;
};

// ---------------------------------------------------------------------------
// Viewer stream

/// What the lock-step PVS streams (ViewerSession, TickSession) share: the
/// call, the first message that names the scene and the encoding, a
/// protocol error that cancels the call, and the ending.
template <class Request, class Response>
class PvsStreamSession {
 public:
  PvsStreamSession(const PvsStreamSession&) = delete;
  PvsStreamSession& operator=(const PvsStreamSession&) = delete;

  /// Ends the stream (WritesDone, then the final status). A protocol error
  /// seen before (a delta that does not apply, an answer to another request)
  /// comes back as INTERNAL with a message starting "protocol: ";
  /// protocol_error() then tells it from the server's own INTERNAL.
  grpc::Status finish() {
    if (stream_ == nullptr) return grpc::Status(grpc::StatusCode::FAILED_PRECONDITION, "not open");
    if (finished_) return grpc::Status(grpc::StatusCode::FAILED_PRECONDITION, "already finished");
    finished_ = true;
    if (protocol_error_.empty()) stream_->WritesDone();
    const grpc::Status status = stream_->Finish();
    if (!protocol_error_.empty()) return grpc::Status(grpc::StatusCode::INTERNAL, protocol_error_);
    return status;
  }
  bool protocol_error() const { return !protocol_error_.empty(); }

 protected:
  using Start = std::unique_ptr<grpc::ClientReaderWriter<Request, Response>> (v1::Visibility::Stub::*)(
      grpc::ClientContext*);
  explicit PvsStreamSession(const Client& client) : client_(client) {}
  ~PvsStreamSession() {  ///< Cancels the stream if finish() was not called.
    if (context_ != nullptr && !finished_) {
      context_->TryCancel();
      if (stream_ != nullptr) stream_->Finish();
    }
  }
  /// Starts a call of `start` (the stub's View or Tick).
  void start(Start method, const std::string& scene_id, v1::PvsEncoding encoding) {
    context_ = std::make_unique<grpc::ClientContext>();
    client_.prepare(context_.get(), std::chrono::milliseconds(0));
    stream_ = (client_.stub().*method)(context_.get());
    scene_id_ = scene_id;
    encoding_ = encoding;
    first_ = true;
    finished_ = false;
    protocol_error_.clear();
  }
  /// Whether the stream may send; sets the scene and encoding on the first.
  bool ready(Request* request) {
    if (stream_ == nullptr || finished_ || !protocol_error_.empty()) return false;
    if (first_) {
      request->set_scene_id(scene_id_);
      request->set_encoding(encoding_);
      first_ = false;
    }
    return true;
  }
  /// Records a protocol error and cancels the call; returns false.
  bool fail(std::string message) {
    protocol_error_ = std::move(message);
    context_->TryCancel();
    return false;
  }

  const Client& client_;
  std::unique_ptr<grpc::ClientContext> context_;
  std::unique_ptr<grpc::ClientReaderWriter<Request, Response>> stream_;
  std::string scene_id_;
  v1::PvsEncoding encoding_ = v1::PVS_FULL;
  bool first_ = true;
  bool finished_ = false;
  std::vector<ObjectId> scratch_;
  std::string protocol_error_;
};

/// One answer of ViewerSession::frame.
struct ViewFrame {
  std::uint64_t frame = 0;      ///< The request's frame number, echoed.
  double t = 0.0;               ///< Scene time the frame was computed at, seconds.
  FrameResult result;           ///< Full PVS (deltas reassembled), wake, stats.
  std::uint32_t frames_skipped = 0;  ///< Requests replaced by newer ones (0 in lock-step).
  double server_us = 0.0;       ///< Server time for the request, microseconds.
};

/// The View stream, lock-step: frame() writes one request and waits for its
/// answer.
class ViewerSession : public PvsStreamSession<v1::ViewRequest, v1::ViewResponse> {
 public:
  explicit ViewerSession(const Client& client) : PvsStreamSession(client) {}

  /// Starts the stream. The scene and encoding go with the first frame, so an
  /// unknown scene shows as a failed frame().
  void open(const std::string& scene_id, v1::PvsEncoding encoding = v1::PVS_FULL);

  /// Sends frame `frame_no` (must increase along the stream) at time `t`
  /// (seconds, not decreasing) and waits for its answer. On failure returns
  /// false; finish() then gives the reason.
  bool frame(std::uint64_t frame_no, double t, const Camera& camera, ViewFrame* out);

 private:
  std::vector<ObjectId> pvs_;  ///< Previous answer's PVS, for deltas.
};

/// Applies a change to an ascending id set: `ids` minus `removed` plus
/// `added`, both ascending. Returns false (with `ids` unchanged) when a list
/// is not strictly ascending, a removed id is absent or an added id already
/// present; `error` then names the list by `removed_name` / `added_name`.
/// `scratch` is reused working memory.
bool apply_delta(std::vector<ObjectId>* ids, const std::vector<ObjectId>& removed,
                 const std::vector<ObjectId>& added, std::vector<ObjectId>* scratch,
                 std::string* error, const char* removed_name = "removed",
                 const char* added_name = "added");

/// An IdSet (gaps or bitset) as ascending ids. Returns false, with `error`
/// saying why, when it holds both forms, a gap of 0 after the first id (ids
/// not strictly ascending), or an id past 2^32 - 1.
bool ids_from_proto(const v1::IdSet& in, std::vector<ObjectId>* out, std::string* error);

/// A wake list as the server sends it on Simulate and Tick streams, with the
/// whole list after each change.
class WakeTracker {
 public:
  /// Applies one WakeList message; false with `error` when it does not fit
  /// (a version that does not increase, a first list that is not full, a
  /// change that does not apply, a size that disagrees).
  bool apply(const v1::WakeList& wake, std::string* error);
  bool have() const { return have_; }
  const std::vector<ObjectId>& ids() const { return ids_; }
  std::uint64_t version() const { return version_; }

 private:
  bool have_ = false;
  std::uint64_t version_ = 0;
  std::vector<ObjectId> ids_;
  std::vector<ObjectId> scratch_;
};

// ---------------------------------------------------------------------------
// Tick stream

/// One viewer of a tick: the id the client chose for it, and its camera.
struct TickCamera {
  std::uint64_t viewer = 0;
  Camera camera;
};

/// One viewer's answer in a tick.
struct TickViewerAnswer {
  std::uint64_t viewer = 0;
  /// Empty when answered; else the refused field ("viewers[2].camera.near")
  /// and what is wrong with it.
  std::string error_field, error;
  double t = 0.0;      ///< Scene time its frame was computed at, seconds.
  FrameResult result;  ///< Full PVS (deltas reassembled), the frame's wake, stats.
};

/// One answer of TickSession::tick.
struct TickAnswer {
  std::uint64_t tick = 0;
  std::vector<TickViewerAnswer> viewers;  ///< In the request's order.
  bool wake_changed = false;              ///< The scene's wake list changed (TickSession::wake()).
  std::uint32_t ticks_skipped = 0;        ///< Ticks replaced by newer ones (0 in lock-step).
  std::uint32_t moves_applied = 0;
  std::vector<ObjectId> too_fast;         ///< Moved faster than their max_speed (applied anyway).
  double server_us = 0.0;
};

/// The Tick stream, lock-step: tick() writes one tick and waits for its
/// answer. Keeps each viewer's PVS for deltas and the scene's wake list.
class TickSession : public PvsStreamSession<v1::TickRequest, v1::TickResponse> {
 public:
  explicit TickSession(const Client& client) : PvsStreamSession(client) {}

  /// Starts the stream; the scene and encoding go with the first tick.
  void open(const std::string& scene_id, v1::PvsEncoding encoding = v1::PVS_FULL);
  /// Sends tick `tick_no` (must increase) at time `t` (seconds, not
  /// decreasing) with `moves` (need the simulation role; may be empty), the
  /// cameras of `viewers`, and the viewers that are gone (`left`, dropped
  /// before the frames); waits for the answer. On failure returns false;
  /// finish() then gives the reason. A viewer refused by the server (a bad
  /// camera) is not a failure: its entry says why.
  bool tick(std::uint64_t tick_no, double t, const std::vector<Move>& moves, const std::vector<TickCamera>& viewers,
            const std::vector<std::uint64_t>& left, TickAnswer* out);
  /// The scene's wake list as last sent (empty before the first).
  const std::vector<ObjectId>& wake() const { return wake_.ids(); }

 private:
  std::unordered_map<std::uint64_t, std::vector<ObjectId>> pvs_;  ///< Each viewer's previous PVS.
  std::vector<ObjectId> added_, removed_;
  WakeTracker wake_;
};

// ---------------------------------------------------------------------------
// Simulation stream

struct MoveAckResult {
  std::uint64_t seq = 0;
  std::uint32_t applied = 0;
  std::vector<ObjectId> too_fast;  ///< Moved faster than their max_speed (applied anyway).
  double t = 0.0;                  ///< Scene time the batch was applied at, seconds.
};

/// A wake-list change, with the whole list after it.
struct WakeUpdate {
  std::uint64_t version = 0;
  bool full = false;              ///< The server sent the whole list.
  std::vector<ObjectId> ids;      ///< Whole list after the change, ascending.
};

/// The Simulate stream, lock-step: send() writes one batch and reads until
/// its acknowledgement, collecting the wake-list changes that come first.
class SimulationSession {
 public:
  explicit SimulationSession(const Client& client) : client_(client) {}
  ~SimulationSession();  ///< Cancels the stream if finish() was not called.
  SimulationSession(const SimulationSession&) = delete;
  SimulationSession& operator=(const SimulationSession&) = delete;

  /// Starts the stream and subscribes to the scene's wake list. On failure
  /// returns false; finish() gives the reason.
  bool open(const std::string& scene_id);

  /// Sends a batch at time `t` (seconds, not decreasing) and waits for the
  /// acknowledgement of `seq`. Wake-list changes read meanwhile are appended
  /// to `wakes` (may be null), in stream order. On failure returns false.
  bool send(std::uint64_t seq, double t, const std::vector<Move>& moves, MoveAckResult* ack,
            std::vector<WakeUpdate>* wakes);

  /// The reassembled wake list (ascending) and its version; empty before the
  /// first wake message.
  const std::vector<ObjectId>& wake() const { return wake_.ids(); }
  std::uint64_t wake_version() const { return wake_.version(); }

  /// Ends the stream: WritesDone, then reads what is left (wake-list changes
  /// go to `wakes`, may be null) and returns the final status. Protocol
  /// errors as in ViewerSession::finish().
  grpc::Status finish(std::vector<WakeUpdate>* wakes = nullptr);
  bool protocol_error() const { return !protocol_error_.empty(); }

 private:
  bool fail(std::string message);
  bool apply_wake(const v1::WakeList& wake, std::vector<WakeUpdate>* wakes);

  const Client& client_;
  std::unique_ptr<grpc::ClientContext> context_;
  std::unique_ptr<grpc::ClientReaderWriter<v1::SimulateRequest, v1::SimulateResponse>> stream_;
  bool finished_ = false;
  WakeTracker wake_;
  std::string protocol_error_;
};

}  // namespace voxvis::client
