// common.h — helpers shared by the `voxvis` subcommands: file reading,
// percentiles, the progress line, and connecting to voxvis-server with the
// options every networked command takes.
#pragma once

#include <chrono>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <grpcpp/grpcpp.h>

#include "cli.h"
#include "voxvis/client.h"
#include "voxvis/format.h"
#include "voxvis/routing.h"

namespace voxvis::cli {

/// Reads a whole file; on error sets `error` ("<path>: cannot open: ...").
bool read_file(const std::string& path, std::string* text, FormatError* error);

/// Whether a frames line is blank (only spaces, tabs or '\r'): skipped, but counted.
bool blank(const std::string& line);

/// Reads a frames file (JSON Lines) whole: its frames, and each one's line
/// in the file (`lines`, may be null). On error reports it (file:line) and
/// returns false; a file without a frame is an error saying that `what`
/// needs one.
bool read_frames(const std::string& path, const char* what, std::vector<FrameInput>* frames,
                 std::vector<int>* lines = nullptr);

/// Nearest-rank percentile of sorted values, p in (0, 100].
double percentile(const std::vector<double>& sorted, double p);

/// Mean, median and 99th percentile of per-frame values (0 when empty).
struct Spread {
  double mean = 0.0, median = 0.0, p99 = 0.0;
};
Spread spread(std::vector<double> values);

/// 1234567 -> "1,234,567".
std::string with_commas(std::uint64_t n);

/// "voxvis: frame N, F fps" on stderr, at most twice a second, when enabled;
/// with a total, a bar, the percentage and the time left.
class Progress {
 public:
  explicit Progress(bool enabled, std::size_t total = 0) : enabled_(enabled), total_(total) {}
  void update(std::size_t frames);
  void finish();
  double elapsed() const { return std::chrono::duration<double>(Clock::now() - start_).count(); }

 private:
  using Clock = std::chrono::steady_clock;
  bool enabled_;
  std::size_t total_;
  bool shown_ = false;
  Clock::time_point start_ = Clock::now();
  Clock::time_point last_ = Clock::now();
};

/// Prints "voxvis: error: <message>" on stderr and returns kExitError.
int report_message(const std::string& message);

/// Reports a failed call or stream. A protocol error (the server broke the
/// contract) is internal (kExitInternal); any status from the server is
/// kExitError. `where` (may be empty) prefixes the message, e.g. "frames.jsonl:12".
int report_status(const grpc::Status& status, const std::string& address, const std::string& where,
                  bool protocol_error = false);

/// Whether a server error is about what the client sent (so that the message
/// should name the input's file and line): INVALID_ARGUMENT, OUT_OF_RANGE,
/// FAILED_PRECONDITION, RESOURCE_EXHAUSTED.
bool about_input(grpc::StatusCode code);

/// Loads the token (--token-file, else $VOXVIS_TOKEN_FILE, else none) and
/// creates a client. On error reports it, sets `*exit_code` and returns nullptr.
/// `channel_index` > 0 asks for a connection of its own.
std::unique_ptr<client::Client> open_client(const NetArgs& net, int* exit_code,
                                            int channel_index = 0);

/// The servers a command visits: the fleet of `net.servers`, else `net.server`
/// alone (named by its address). On error (a bad list) reports it, sets
/// `*exit_code` and returns false.
bool fleet_of(const NetArgs& net, std::vector<routing::Shard>* shards, int* exit_code);

/// Loads the token as open_client does. On error reports it and returns false.
bool resolve_token(const NetArgs& net, std::string* token);

/// Checks a scene id as the server does: 1 to 64 characters from
/// [A-Za-z0-9._-], not starting with '.'. On error sets `message`.
bool valid_scene_id(const std::string& id, std::string* message);

}  // namespace voxvis::cli
