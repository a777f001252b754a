// server_process.h — the harness of the integration tests: the real
// voxvis-server binary (VOXVIS_SERVER, or the one the environment variable
// VOXVIS_TEST_SERVER names) run as a child process on a loopback port, and
// thin wrappers around the generated gRPC stubs.
//
// Design choices:
//  * The tests talk to the server through the generated stubs only
//    (voxvis::v1::Visibility::Stub, sync API), never through the client
//    library, so that they check the wire contract itself.
//  * Every wait is bounded: process start, exit, stream reads (through call
//    deadlines) and polls. A test that hangs is a failing test.
//  * One fresh temporary directory per ServerProcess (mkdtemp under
//    $TMPDIR or /tmp) holds the data directory, the port file and the
//    server's stderr, which is printed when the test has failed. The
//    directory is removed at the end unless VOXVIS_KEEP_TEST_DIRS is set.
//  * The child is killed (SIGKILL) in the destructor whatever happened.
#pragma once

#include <sys/types.h>

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include "files.h"
#include "voxvis/client.h"
#include "voxvis/scene.h"
#include "voxvis/types.h"
#include "voxvis/v1/voxvis.grpc.pb.h"

namespace voxvis::servertest {

using Seconds = std::chrono::duration<double>;

// ---------------------------------------------------------------------------
// Files and processes

/// Creates a fresh directory under $TMPDIR (or /tmp); aborts the test on error.
std::string make_temp_dir(const std::string& prefix);
using test::lines_of;
using test::slurp;
using test::spit;

/// Polls `done` every few milliseconds until it is true or `timeout` passes.
template <class Pred>
bool wait_until(Pred done, Seconds timeout) {
  const auto end = std::chrono::steady_clock::now() + timeout;
  while (!done()) {
    if (std::chrono::steady_clock::now() >= end) return done();
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return true;
}

struct ProcessResult {
  int status = -1;  ///< Exit status; -1 when killed by a signal or timed out.
  int signal = 0;   ///< Signal that ended it, if any.
  bool timed_out = false;
  std::string out, err;
};

/// Runs argv[0] with stdin from /dev/null, stdout and stderr captured
/// through files in `dir`; kills it (SIGKILL) after `timeout`.
ProcessResult run_program(const std::vector<std::string>& argv, const std::string& dir,
                          Seconds timeout = Seconds(120));

/// Makes a self-signed certificate for the name "voxvis.test" (its subject and
/// subjectAltName) with openssl: PEM files `cert` and `key`.
::testing::AssertionResult make_test_certificate(const std::string& cert, const std::string& key,
                                                 const std::string& dir);

/// A child process started with posix_spawn; killed in the destructor.
class ChildProcess {
 public:
  ChildProcess() = default;
  ~ChildProcess();
  ChildProcess(const ChildProcess&) = delete;
  ChildProcess& operator=(const ChildProcess&) = delete;

  /// Starts argv[0]; stdout and stderr go to the files (appended). `env`
  /// entries ("NAME=value") are added to (or replace those of) the test's
  /// environment.
  bool spawn(const std::vector<std::string>& argv, const std::string& stdout_path,
             const std::string& stderr_path, const std::vector<std::string>& env = {});
  pid_t pid() const { return pid_; }
  bool running();
  /// Waits for the exit (bounded). Returns the exit status, -1 when killed by
  /// a signal (`signal()` says which) or still running after `timeout`.
  int wait(Seconds timeout);
  int signal() const { return signal_; }
  void send_signal(int sig);
  /// SIGKILL and reap.
  void kill9();

 private:
  pid_t pid_ = -1;  // Negated once reaped.
  int signal_ = 0;
  int exited_status_ = -1;
};

// ---------------------------------------------------------------------------
// API wrappers

/// A stub and the token it sends ("authorization: Bearer <token>").
class Api {
 public:
  Api(std::shared_ptr<grpc::Channel> channel, std::string token);

  v1::Visibility::Stub& stub() const { return *stub_; }
  const std::shared_ptr<grpc::Channel>& channel() const { return channel_; }
  const std::string& token() const { return token_; }
  /// Adds the token (when not empty) and a deadline `timeout` from now.
  void prepare(grpc::ClientContext* context, Seconds timeout = Seconds(30)) const;

  grpc::Status create_scene(const std::string& id, const v1::SceneDescription& desc,
                            v1::SceneInfo* info = nullptr) const;
  grpc::Status create_scene_json(const std::string& id, const std::string& json,
                                 v1::SceneInfo* info = nullptr) const;
  grpc::Status delete_scene(const std::string& id) const;
  /// Scene ids in the order the server lists them.
  grpc::Status list_scenes(std::vector<std::string>* ids) const;
  grpc::Status stats(const std::string& id, v1::SceneInfo* info) const;
  grpc::Status export_scene(const std::string& id, v1::ExportSceneResponse* out) const;
  grpc::Status get_pvs(const std::string& id, double t, const Camera& camera,
                       v1::GetPvsResponse* out) const;

 private:
  std::shared_ptr<grpc::Channel> channel_;
  std::unique_ptr<v1::Visibility::Stub> stub_;
  std::string token_;
};

/// One View stream, driven with the sync API.
class ViewStream {
 public:
  /// Opens the stream (the scene and encoding go with the first request).
  ViewStream(const Api& api, std::string scene_id, v1::PvsEncoding encoding = v1::PVS_FULL,
             Seconds timeout = Seconds(120));
  ~ViewStream();

  /// Writes one request; false when the stream is broken.
  bool send(std::uint64_t frame, double t, const Camera& camera);
  bool send(const v1::ViewRequest& request);
  bool read(v1::ViewResponse* response);
  /// send + read.
  bool frame(std::uint64_t frame, double t, const Camera& camera, v1::ViewResponse* response);
  /// Half-closes (once).
  bool writes_done();
  /// Half-closes (once), reads what is left (counted in `drained()`) and
  /// returns the call's status.
  grpc::Status finish();
  std::size_t drained() const { return drained_; }
  grpc::ClientContext& context() { return context_; }
  grpc::ClientReaderWriter<v1::ViewRequest, v1::ViewResponse>& stream() { return *stream_; }

 private:
  grpc::ClientContext context_;
  std::unique_ptr<grpc::ClientReaderWriter<v1::ViewRequest, v1::ViewResponse>> stream_;
  std::string scene_id_;
  v1::PvsEncoding encoding_;
  bool first_ = true;
  bool writes_done_ = false;
  bool finished_ = false;
  grpc::Status status_;
  std::size_t drained_ = 0;
};

/// One Simulate stream. A background thread reads every answer: wake lists
/// are reassembled (and checked: the first one full, versions increasing,
/// deltas consistent), acknowledgements are queued for wait_ack.
class SimStream {
 public:
  /// Opens the stream and subscribes (first message: scene id, no batch).
  SimStream(const Api& api, std::string scene_id, Seconds timeout = Seconds(120));
  ~SimStream();

  bool send(std::uint64_t seq, double t, const std::vector<Move>& moves);
  /// The next acknowledgement, waiting at most `timeout`; false when the
  /// stream ended or the time ran out.
  bool wait_ack(v1::MoveAck* ack, Seconds timeout = Seconds(30));
  /// send + wait_ack.
  bool move(std::uint64_t seq, double t, const std::vector<Move>& moves, v1::MoveAck* ack);

  /// Every wake list reassembled so far, one entry per WakeList message.
  std::vector<std::vector<ObjectId>> wake_history() const;
  /// Waits until more than `count` wake lists have arrived (or the stream ended).
  bool wait_wake_count(std::size_t count, Seconds timeout);
  /// Inconsistencies found in the wake-list messages.
  std::vector<std::string> protocol_errors() const;
  bool ended() const;

  /// Half-closes, waits for the reader and returns the call's status.
  grpc::Status finish();
  grpc::ClientContext& context() { return context_; }

 private:
  void read_loop();

  grpc::ClientContext context_;
  std::unique_ptr<grpc::ClientReaderWriter<v1::SimulateRequest, v1::SimulateResponse>> stream_;
  std::string scene_id_;
  bool writes_done_ = false;
  bool finished_ = false;
  grpc::Status status_;
  std::thread reader_;

  mutable std::mutex mu_;
  std::condition_variable cv_;
  std::deque<v1::MoveAck> acks_;                // Guarded by mu_.
  std::vector<ObjectId> wake_;                  // Guarded by mu_.
  std::vector<std::vector<ObjectId>> history_;  // Guarded by mu_.
  std::uint64_t version_ = 0;                   // Guarded by mu_.
  std::vector<std::string> errors_;             // Guarded by mu_.
  bool ended_ = false;                          // Guarded by mu_.
};

/// `count` GetPvs calls sent at once on one channel without waiting for any
/// (gRPC's callback client API), each with its own deadline `timeout`: the
/// flood a careless or hostile client makes. Completions are counted by
/// status code; the destructor waits for every call (cancelling what is left
/// after a bound).
class PvsFlood {
 public:
  PvsFlood(const Api& api, const std::string& scene_id, int count, double t, const Camera& camera,
           Seconds timeout);
  ~PvsFlood();
  PvsFlood(const PvsFlood&) = delete;
  PvsFlood& operator=(const PvsFlood&) = delete;

  int count() const { return static_cast<int>(calls_.size()); }
  /// Calls completed so far, whatever their status.
  int done() const;
  /// Calls completed with `code` so far.
  int with_code(grpc::StatusCode code) const;
  /// Waits until every call has completed; false when `timeout` passed first.
  bool wait_all(Seconds timeout) const;
  /// Cancels every call still open.
  void cancel();

 private:
  struct Call {
    grpc::ClientContext context;
    v1::GetPvsRequest request;
    v1::GetPvsResponse response;
  };
  std::vector<std::unique_ptr<Call>> calls_;
  mutable std::mutex mu_;
  mutable std::condition_variable cv_;
  int done_ = 0;                          // Guarded by mu_.
  std::map<grpc::StatusCode, int> codes_;  // Guarded by mu_.
};

/// A status for a failure message: its code as a number, then its message.
std::string show(const grpc::Status& s);

/// GET http://127.0.0.1:port/path over HTTP/1.0: the whole answer, headers
/// included, or a line saying what failed.
std::string http_get(int port, const std::string& path);

/// The whole number that ends just before the first `marker` in `text`
/// ("12 queued requests dropped" with marker " queued"); -1 when there is none.
long number_before(const std::string& text, const std::string& marker);

// ---------------------------------------------------------------------------
// The server process

/// Server arguments for tests that compare its answers with `voxvis replay`
/// counter for counter, `more` first: no periodic position save. A save
/// reads the scene under its lock, and a frame that ends while any reader
/// holds it leaves its queued TBV work to the next frame (conservative;
/// docs/design.md, *Thread-safety*, step 4), which would shift counters by a
/// frame. Positions are still saved when the server stops.
inline std::vector<std::string> replay_exact_args(std::vector<std::string> more = {}) {
  more.insert(more.end(), {"--save-period", "1e6"});
  return more;
}

class ServerProcess {
 public:
  /// `extra_args` follow --listen, --port-file and --data-dir.
  explicit ServerProcess(std::vector<std::string> extra_args = {});
  ~ServerProcess();
  ServerProcess(const ServerProcess&) = delete;
  ServerProcess& operator=(const ServerProcess&) = delete;

  /// Starts the server and waits (at most 20 s) for its port file.
  ::testing::AssertionResult start();
  /// Starts it again on the same data directory (after terminate or kill9).
  ::testing::AssertionResult restart() { return start(); }

  std::vector<std::string>& extra_args() { return extra_args_; }
  /// "NAME=value" entries added to the server's environment.
  std::vector<std::string>& extra_env() { return extra_env_; }
  std::string address() const { return "127.0.0.1:" + std::to_string(port_); }
  int port() const { return port_; }
  pid_t pid() const { return child_ ? child_->pid() : -1; }
  bool running() const { return child_ && child_->running(); }
  /// The test's temporary directory and the server's data directory in it.
  const std::string& dir() const { return dir_; }
  std::string data_dir() const { return dir_ + "/data"; }
  /// Path for a scratch file of the test.
  std::string path(const std::string& name) const { return dir_ + "/" + name; }

  /// A new channel on its own TCP connection. `int_args` are extra channel
  /// arguments (for example {GRPC_ARG_HTTP2_BDP_PROBE, 0}).
  std::shared_ptr<grpc::Channel> channel(
      const std::vector<std::pair<std::string, int>>& int_args = {}) const;
  /// A stub on a new channel, sending `token` when not empty.
  Api api(const std::string& token = "") const;

  /// SIGTERM, then waits (bounded); returns the exit status (-1 when killed
  /// by a signal or not exited within `timeout`, in which case it is killed).
  int terminate(Seconds timeout = Seconds(30));
  /// Sends a signal without waiting.
  void signal(int sig);
  /// Waits for the exit; the exit status, or -1 (killed by a signal, or
  /// still running after `timeout`: then it is killed and the test fails).
  int wait_exit(Seconds timeout);
  void kill9();
  /// The server's resident set size (VmRSS), KiB; -1 when unreadable.
  long rss_kib() const;
  /// The server's peak resident set size so far (VmHWM), KiB; -1 when unreadable.
  long peak_rss_kib() const;
  /// Sets the peak (VmHWM) back to the present resident size, so that the
  /// next peak_rss_kib() is that of what happens from now on (Linux's
  /// /proc/PID/clear_refs); false when the kernel refuses.
  bool reset_peak_rss() const;
  /// CPU time the server has used so far (user and system, all threads),
  /// seconds; -1 when unreadable.
  double cpu_seconds() const;
  /// The server's stderr so far (all runs).
  std::string log() const;
  /// The port of the metrics endpoint the log announced (with --metrics
  /// HOST:0); 0 when it has not.
  int metrics_port() const;

 private:
  std::vector<std::string> extra_args_;
  std::vector<std::string> extra_env_;
  std::string dir_;
  std::unique_ptr<ChildProcess> child_;
  int port_ = 0;
};

// ---------------------------------------------------------------------------
// Calls by method name, with serialized messages (grpc::GenericStub): for
// services whose generated code the tests do not have (health, reflection).

/// A unary call; `timeout` is the call's deadline; `token`, when not empty,
/// goes as "authorization: Bearer <token>".
grpc::Status generic_unary(const std::shared_ptr<grpc::Channel>& channel, const std::string& method,
                           const std::string& request, std::string* response,
                           Seconds timeout = Seconds(10), const std::string& token = "");
/// A bidi-streaming call that sends one message, half-closes, and collects
/// every answer.
grpc::Status generic_bidi(const std::shared_ptr<grpc::Channel>& channel, const std::string& method,
                          const std::string& request, std::vector<std::string>* responses,
                          Seconds timeout = Seconds(10), const std::string& token = "");

// ---------------------------------------------------------------------------
// Scenes, cameras and conversions shared by the tests

// Engine values as messages: the client library's conversions (the server
// converts back with its own code, so the two are checked against each other).
using voxvis::client::to_proto;
std::vector<ObjectId> ids_of(const google::protobuf::RepeatedField<std::uint32_t>& ids);
/// The stats counters, everything but time_us, as one line of name=value pairs.
std::string counters(const FrameStats& s);
std::string counters(const v1::FrameStats& s);

/// A camera at `eye` looking along `dir`, 60 degrees, far 1000.
Camera look(Vec3 eye, Vec3 dir);

/// A small scene as text: bounds [0,20]^3, grid 20^3; a wall (id 1) filling
/// z in [8.5, 11.5] (it covers the voxel layers 9 and 10 with a margin: a
/// face exactly on a voxel boundary is not trusted to occlude); a dynamic
/// sphere (id 2, max_speed 100) behind it at (10, 10, 15); a static sphere
/// (id 3) in front at (10, 10, 5). A camera at (10, 10, 1) looking +z
/// (wall_camera()) sees 1 and 3, not 2.
std::string wall_scene_json();

/// CreateScene of a description with its own deadline.
grpc::Status create_with_deadline(const Api& api, const std::string& id, const v1::SceneDescription& d,
                                  Seconds timeout);
Camera wall_camera();

/// `count` small spheres (ids 1..count) on a jittered lattice in
/// [0,100]^3, a fifth of them dynamic (max_speed 5), grid `grid`^3, no
/// occluders: from outside looking in, nearly all are visible.
SceneDesc lattice_scene(int count, int grid, std::uint64_t seed);

/// `count` spheres of radius 1e12 scattered in bounds of +-1e12, no grid:
/// each touches most of the automatic grid, so that the scene's id lists
/// hold about objects x voxels entries (the careless admin's scene).
SceneDesc huge_footprint_scene(int count);

/// Compares two output files of `voxvis replay` format: every line's frame,
/// pvs, wake and every stats counter but the times (time_us and its split).
void expect_same_output(const std::string& expected_text, const std::string& actual_text,
                        const std::string& what);

}  // namespace voxvis::servertest
