// simulate_cmd.cpp — `voxvis simulate`: a simulation backend in a file. Each
// frames line's moves go to the server as one batch; every wake-list change
// the server reports comes out as one JSON line, with the whole list, so a
// script can follow which objects it must keep simulating.
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <CLI/CLI.hpp>

#include "cli.h"
#include "common.h"
#include "options.h"
#include "voxvis/client.h"
#include "voxvis/format.h"

namespace voxvis::cli {
namespace {

/// {"seq":S,"version":V,"size":N,"wake":[...]}; seq is null before the first ack.
void print_wake(const std::optional<std::uint64_t>& seq, const client::WakeUpdate& w) {
  std::string line = "{\"seq\":";
  line += seq ? std::to_string(*seq) : "null";
  line += ",\"version\":" + std::to_string(w.version);
  line += ",\"size\":" + std::to_string(w.ids.size());
  line += ",\"wake\":[";
  for (std::size_t i = 0; i < w.ids.size(); ++i) {
    if (i > 0) line += ',';
    line += std::to_string(w.ids[i]);
  }
  line += "]}\n";
  std::fwrite(line.data(), 1, line.size(), stdout);
}

}  // namespace

int run_simulate(const SimulateArgs& args) {
  std::string message;
  if (!valid_scene_id(args.scene, &message)) return report(FormatError{"", 0, "--scene", message});
  if (!std::isfinite(args.rate) || args.rate < 0.0) {
    return report(FormatError{"", 0, "--rate", "must be a finite number of batches per second >= 0 (0: as fast as acknowledged)"});
  }
  std::ifstream frames(args.frames, std::ios::binary);
  if (!frames) {
    return report(FormatError{args.frames, 0, "", std::string("cannot open: ") + std::strerror(errno)});
  }

  int code = kExitOk;
  const std::unique_ptr<client::Client> client = open_client(args.net, &code);
  if (client == nullptr) return code;
  client::SimulationSession sim(*client);
  if (!sim.open(args.scene)) {
    const grpc::Status st = sim.finish();
    return report_status(st, args.net.server, "", sim.protocol_error());
  }

  using Clock = std::chrono::steady_clock;
  const Clock::time_point start = Clock::now();
  FrameInput frame;
  FormatError error;
  client::MoveAckResult ack;
  std::vector<client::WakeUpdate> wakes;
  std::optional<std::uint64_t> last_ack;
  std::uint64_t batches = 0;
  std::uint64_t moves = 0;
  std::uint64_t too_fast = 0;
  std::uint64_t changes = 0;
  int line_no = 0;
  std::string line;
  const auto flush_wakes = [&] {
    for (const client::WakeUpdate& w : wakes) print_wake(last_ack, w);
    changes += wakes.size();
    wakes.clear();
    std::fflush(stdout);  // A consumer on a pipe sees each change as it happens.
  };

  while (std::getline(frames, line)) {
    ++line_no;
    if (blank(line)) continue;
    if (!parse_frame_line(line, args.frames, line_no, &frame, &error)) return report(error);
    if (args.rate > 0.0) {
      std::this_thread::sleep_until(
          start + std::chrono::duration_cast<Clock::duration>(
                      std::chrono::duration<double>(static_cast<double>(batches) / args.rate)));
    }
    const std::uint64_t seq = batches;
    if (!sim.send(seq, frame.t, frame.moves, &ack, &wakes)) {
      flush_wakes();
      const grpc::Status st = sim.finish();
      const bool about_line = sim.protocol_error() || about_input(st.error_code());
      return report_status(st, args.net.server,
                           about_line ? args.frames + ":" + std::to_string(line_no) : "",
                           sim.protocol_error());
    }
    flush_wakes();  // Changes that came before this batch's ack.
    last_ack = seq;
    ++batches;
    moves += frame.moves.size();
    too_fast += ack.too_fast.size();
  }
  if (frames.bad()) {
    return report(FormatError{args.frames, line_no, "", std::string("cannot read: ") + std::strerror(errno)});
  }
  const grpc::Status st = sim.finish(&wakes);
  flush_wakes();
  if (!st.ok()) return report_status(st, args.net.server, "", sim.protocol_error());
  if (std::ferror(stdout) != 0) {
    return report(FormatError{"<stdout>", 0, "", std::string("cannot write: ") + std::strerror(errno)});
  }

  if (!args.quiet) {
    const double wall = std::chrono::duration<double>(Clock::now() - start).count();
    std::fprintf(stderr,
                 "voxvis: %s batches, %s moves in %.2f s; too-fast moves %s; %s wake-list "
                 "changes, now %zu objects (version %llu)\n",
                 with_commas(batches).c_str(), with_commas(moves).c_str(), wall,
                 with_commas(too_fast).c_str(), with_commas(changes).c_str(), sim.wake().size(),
                 static_cast<unsigned long long>(sim.wake_version()));
  }
  return kExitOk;
}

Command add_simulate_command(CLI::App& app) {
  auto args = std::make_shared<SimulateArgs>();
  CLI::App* cmd = app.add_subcommand(
      "simulate", "Send a frames file's moves to the server and print wake-list changes.");
  add_net_options(cmd, &args->net);
  cmd->add_option("--scene", args->scene, "Scene id on the server")->required()->type_name("ID");
  cmd->add_option("--frames", args->frames, "Frames file; each line's moves are one batch")
      ->required()
      ->type_name("FILE");
  cmd->add_option("--rate", args->rate,
                  "Batches per second, paced by the wall clock (default: as fast as "
                  "acknowledged)")
      ->type_name("HZ");
  cmd->add_flag("-q,--quiet", args->quiet, "No summary on stderr");
  cmd->footer(
      "Batch seq = 0-based line index, t = the line's t. Output: one line per wake-list\n"
      "change, {\"seq\": <latest ack before it, null before any>, \"version\", \"size\",\n"
      "\"wake\": [the whole list, ascending]}. Needs a simulation token.");
  return {cmd, [args] { return run_routed(&args->net, args->scene, [&] { return run_simulate(*args); }); }};
}

}  // namespace voxvis::cli
