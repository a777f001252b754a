// view_cmd.cpp — `voxvis view`: `voxvis replay` against a server. Each frames
// line's moves go through a Simulate stream (acknowledged before the frame),
// then its camera through a View stream, lock-step; each answer becomes the
// line `voxvis replay` would write, so the two outputs compare line by line
// (apart from the stats' times).
#include <algorithm>
#include <iterator>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include <unistd.h>

#include <CLI/CLI.hpp>

#include "cli.h"
#include "common.h"
#include "options.h"
#include "output_file.h"
#include "voxvis/client.h"
#include "voxvis/format.h"

namespace voxvis::cli {
namespace {

/// Where a stream error is reported: the frames line for errors about what
/// it sent (the server names the field), none for the others (an unknown
/// scene, an unreachable server, a refused token).
std::string where_for(const grpc::Status& st, bool protocol_error, const std::string& file,
                      int line) {
  return protocol_error || about_input(st.error_code()) ? file + ":" + std::to_string(line)
                                                        : std::string();
}

}  // namespace

int run_view(const ViewArgs& args) {
  std::string message;
  if (!valid_scene_id(args.scene, &message)) return report(FormatError{"", 0, "--scene", message});
  RegionOverride region;
  FormatError region_error;
  if (!parse_region_args(args.region, &region, &region_error)) return report(region_error);
  std::ifstream frames(args.frames, std::ios::binary);
  if (!frames) {
    return report(FormatError{args.frames, 0, "", std::string("cannot open: ") + std::strerror(errno)});
  }
  OutputFile out;
  if (!out.open(args.out, &message)) return report(FormatError{args.out, 0, "", message});

  int code = kExitOk;
  const std::unique_ptr<client::Client> client = open_client(args.net, &code);
  if (client == nullptr) return code;
  client::ViewerSession viewer(*client);
  viewer.open(args.scene, args.delta ? v1::PVS_DELTA : v1::PVS_FULL);
  std::unique_ptr<client::SimulationSession> sim;  // Opened at the first moves.

  FrameInput frame;
  FormatError error;
  client::ViewFrame answer;
  client::MoveAckResult ack;
  std::vector<double> round_trips_ms;
  double pvs_total = 0.0;
  std::size_t too_fast = 0;
  std::size_t index = 0;
  std::vector<ObjectId> previous_pvs;  // For --every: the PVS last summarized.
  std::size_t previous_index = 0;
  int line_no = 0;
  std::string line;
  std::string out_line;
  Progress progress(!args.quiet && ::isatty(STDERR_FILENO) != 0);
  const auto fail = [&](int status) {
    progress.finish();
    return status;
  };

  while (std::getline(frames, line)) {
    ++line_no;
    if (blank(line)) continue;
    if (!parse_frame_line(line, args.frames, line_no, &frame, &error)) return fail(report(error));
    region.apply(&frame.camera);
    // Once the file has moved something, every frame's time goes through the
    // simulation stream (an empty batch when it has no moves): the scene's
    // clock follows its simulation, and a viewer runs at most
    // --max-view-lead beyond it, so frames without moves would otherwise be
    // computed at an earlier time than `replay` uses.
    if (!frame.moves.empty() || sim != nullptr) {
      if (sim == nullptr) {
        sim = std::make_unique<client::SimulationSession>(*client);
        if (!sim->open(args.scene)) {
          const grpc::Status st = sim->finish();
          return fail(report_status(st, args.net.server, "", sim->protocol_error()));
        }
      }
      // The frame's index as the batch's sequence number: errors and acks
      // then name the frame.
      if (!sim->send(index, frame.t, frame.moves, &ack, nullptr)) {
        const grpc::Status st = sim->finish();
        return fail(report_status(st, args.net.server,
                                  where_for(st, sim->protocol_error(), args.frames, line_no),
                                  sim->protocol_error()));
      }
      too_fast += ack.too_fast.size();
    }
    const auto sent = std::chrono::steady_clock::now();
    if (!viewer.frame(index, frame.t, frame.camera, &answer)) {
      const grpc::Status st = viewer.finish();
      return fail(report_status(st, args.net.server,
                                where_for(st, viewer.protocol_error(), args.frames, line_no),
                                viewer.protocol_error()));
    }
    round_trips_ms.push_back(
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - sent).count());
    out_line = result_to_json(index, answer.result);
    out_line += '\n';
    if (!out.write(out_line)) {
      return fail(report(FormatError{out.path(), 0, "", std::string("cannot write: ") + std::strerror(errno)}));
    }
    pvs_total += static_cast<double>(answer.result.pvs.size());
    if (args.every > 0 && index % static_cast<std::size_t>(args.every) == 0) {
      const std::vector<ObjectId>& pvs = answer.result.pvs;
      std::vector<ObjectId> diff;
      std::set_difference(pvs.begin(), pvs.end(), previous_pvs.begin(), previous_pvs.end(),
                          std::back_inserter(diff));
      const std::size_t added = diff.size();
      diff.clear();
      std::set_difference(previous_pvs.begin(), previous_pvs.end(), pvs.begin(), pvs.end(),
                          std::back_inserter(diff));
      progress.finish();
      char change[64] = "first frame";
      if (index > 0)
        std::snprintf(change, sizeof change, "+%zu -%zu since frame %zu", added, diff.size(),
                      previous_index);
      std::fprintf(stderr,
                   "frame %4zu  t %7.3f s  PVS %5zu (%s)  wake %4zu  engine %6.2f ms  "
                   "round trip %6.2f ms\n",
                   index, answer.t, pvs.size(), change, answer.result.wake.size(),
                   answer.result.stats.time_us / 1000.0, round_trips_ms.back());
      previous_pvs = pvs;
      previous_index = index;
    }
    ++index;
    progress.update(index);
  }
  if (frames.bad()) {
    return fail(report(FormatError{args.frames, line_no, "", std::string("cannot read: ") + std::strerror(errno)}));
  }
  progress.finish();
  if (const grpc::Status st = viewer.finish(); !st.ok()) {
    return report_status(st, args.net.server, "", viewer.protocol_error());
  }
  if (sim != nullptr) {
    if (const grpc::Status st = sim->finish(); !st.ok()) {
      return report_status(st, args.net.server, "", sim->protocol_error());
    }
  }
  if (!out.commit(&message)) return report(FormatError{out.path(), 0, "", message});

  if (!args.quiet) {
    const double wall = progress.elapsed();
    const Spread sp = spread(round_trips_ms);
    const double n = static_cast<double>(std::max<std::size_t>(round_trips_ms.size(), 1));
    std::fprintf(stderr,
                 "voxvis: %zu frames in %.2f s; round trip ms mean %.2f, median %.2f, p99 %.2f; "
                 "mean PVS %.1f objects; too-fast moves %zu\n",
                 index, wall, sp.mean, sp.median, sp.p99, pvs_total / n, too_fast);
  }
  return kExitOk;
}

Command add_view_command(CLI::App& app) {
  auto args = std::make_shared<ViewArgs>();
  CLI::App* cmd = app.add_subcommand("view", "Replay a frames file against a scene on the server, as one viewer.");
  add_net_options(cmd, &args->net);
  cmd->add_option("--scene", args->scene, "Scene id on the server")->required()->type_name("ID");
  cmd->add_option("--frames", args->frames, "Frames file (JSON Lines: one camera and optional moves per line)")
      ->required()
      ->type_name("FILE");
  cmd->add_option("--out", args->out, "Output file (JSON Lines), written whole or not at all; default stdout")
      ->type_name("FILE");
  cmd->add_flag("--delta", args->delta, "Ask for PVS deltas and reassemble them (same output)");
  add_region_options(cmd, &args->region);
  cmd->add_flag("-q,--quiet", args->quiet, "No progress line and no summary on stderr");
  cmd->add_option("--every", args->every,
                  "Print a one-line summary of every Nth frame on stderr (PVS size and "
                  "change, wake list, engine time, round trip)")
      ->check(CLI::Range(0, 1000000))
      ->type_name("N");
  cmd->footer(
      "Lock-step: a line's moves are sent (Simulate) and acknowledged, then its camera\n"
      "(View, frame number = 0-based frame index, time = the line's t). Output: the\n"
      "lines `voxvis replay` writes, {\"frame\", \"pvs\", \"wake\", \"stats\"}, computed by\n"
      "the server. Moves need a simulation token.");
  return {cmd, [args] { return run_routed(&args->net, args->scene, [&] { return run_view(*args); }); }};
}

}  // namespace voxvis::cli
