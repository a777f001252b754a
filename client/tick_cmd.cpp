// tick_cmd.cpp — `voxvis tick`: a recording replayed against a server as
// ticks of one Tick stream, lock-step. Tick k carries line k's moves and
// time, and one camera per viewer: viewer v walks the recording from its own
// start (line v * n / N, as loadgen's viewers do), so viewer 0 sees exactly
// what `voxvis replay` computes, and its lines compare with replay's line by
// line (apart from the stats' times).
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
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

int run_tick(const TickArgs& args) {
  std::string message;
  if (!valid_scene_id(args.scene, &message)) return report(FormatError{"", 0, "--scene", message});
  if (args.viewers > 1 && args.out.empty())
    return report(FormatError{"", 0, "--out", "with --viewers above 1, name a directory for the viewers' files"});
  RegionOverride region;
  FormatError region_error;
  if (!parse_region_args(args.region, &region, &region_error)) return report(region_error);
  std::vector<FrameInput> frames;
  std::vector<int> lines;  // Each frame's line in the file, for errors.
  if (!read_frames(args.frames, "tick", &frames, &lines)) return kExitError;
  for (FrameInput& f : frames) region.apply(&f.camera);

  // One output a viewer: the file itself for one, DIR/viewer-<k>.jsonl for several.
  const auto viewers = static_cast<std::size_t>(args.viewers);
  std::vector<OutputFile> outs(viewers);
  if (viewers > 1) {
    std::error_code ec;
    std::filesystem::create_directories(args.out, ec);
    if (ec) return report(FormatError{args.out, 0, "", "cannot make the directory: " + ec.message()});
  }
  for (std::size_t v = 0; v < viewers; ++v) {
    const std::string path =
        viewers > 1 ? (std::filesystem::path(args.out) / ("viewer-" + std::to_string(v) + ".jsonl")).string() : args.out;
    if (!outs[v].open(path, &message)) return report(FormatError{path, 0, "", message});
  }

  int code = kExitOk;
  const std::unique_ptr<client::Client> client = open_client(args.net, &code);
  if (client == nullptr) return code;
  client::TickSession session(*client);
  session.open(args.scene, args.delta ? v1::PVS_DELTA : v1::PVS_FULL);

  const std::size_t n = frames.size();
  std::vector<client::TickCamera> cameras(viewers);
  const std::vector<std::uint64_t> none;
  client::TickAnswer answer;
  std::vector<double> round_trips_ms;
  double pvs_total = 0.0;
  std::size_t too_fast = 0;
  std::string out_line;
  Progress progress(!args.quiet && ::isatty(STDERR_FILENO) != 0, n);
  const auto fail = [&](int status) {
    progress.finish();
    return status;
  };
  for (std::size_t k = 0; k < n; ++k) {
    for (std::size_t v = 0; v < viewers; ++v) {
      cameras[v].viewer = v;
      cameras[v].camera = frames[(v * n / viewers + k) % n].camera;
    }
    const auto sent = std::chrono::steady_clock::now();
    if (!session.tick(k, frames[k].t, frames[k].moves, cameras, none, &answer)) {
      const grpc::Status st = session.finish();
      const bool mine = session.protocol_error() || about_input(st.error_code());
      return fail(report_status(st, args.net.server, mine ? args.frames + ":" + std::to_string(lines[k]) : "",
                                session.protocol_error()));
    }
    round_trips_ms.push_back(
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - sent).count());
    too_fast += answer.too_fast.size();
    for (std::size_t v = 0; v < viewers; ++v) {
      const client::TickViewerAnswer& a = answer.viewers[v];
      if (!a.error.empty()) {
        const std::size_t f = (v * n / viewers + k) % n;
        return fail(report(FormatError{args.frames, lines[f], a.error_field, a.error + " (viewer " +
                                                                                 std::to_string(v) + ")"}));
      }
      out_line = result_to_json(k, a.result);
      out_line += '\n';
      if (!outs[v].write(out_line))
        return fail(report(FormatError{outs[v].path(), 0, "", std::string("cannot write: ") + std::strerror(errno)}));
      pvs_total += static_cast<double>(a.result.pvs.size());
    }
    progress.update(k + 1);
  }
  progress.finish();
  if (const grpc::Status st = session.finish(); !st.ok())
    return report_status(st, args.net.server, "", session.protocol_error());
  for (OutputFile& o : outs)
    if (!o.commit(&message)) return report(FormatError{o.path(), 0, "", message});
  if (!args.quiet) {
    const Spread sp = spread(round_trips_ms);
    std::fprintf(stderr,
                 "voxvis: %zu ticks of %zu viewers in %.2f s; round trip ms mean %.2f, median %.2f, p99 %.2f; "
                 "mean PVS %.1f objects; too-fast moves %zu\n",
                 n, viewers, progress.elapsed(), sp.mean, sp.median, sp.p99,
                 pvs_total / static_cast<double>(n * viewers), too_fast);
  }
  return kExitOk;
}

Command add_tick_command(CLI::App& app) {
  auto args = std::make_shared<TickArgs>();
  CLI::App* cmd = app.add_subcommand(
      "tick", "Replay a frames file against a scene on the server as ticks: every viewer in one message.");
  add_net_options(cmd, &args->net);
  cmd->add_option("--scene", args->scene, "Scene id on the server")->required()->type_name("ID");
  cmd->add_option("--frames", args->frames, "Frames file (JSON Lines: one camera and optional moves per line)")
      ->required()
      ->type_name("FILE");
  cmd->add_option("--viewers", args->viewers,
                  "Viewers a tick, each walking the recording from its own start (line v*n/N)")
      ->check(CLI::Range(1, 1024))
      ->type_name("N");
  cmd->add_option("--out", args->out,
                  "One viewer: the output file (default stdout); several: a directory for "
                  "viewer-<k>.jsonl. Written whole or not at all")
      ->type_name("PATH");
  cmd->add_flag("--delta", args->delta, "Ask for PVS deltas and reassemble them (same output)");
  add_region_options(cmd, &args->region);
  cmd->add_flag("-q,--quiet", args->quiet, "No progress line and no summary on stderr");
  cmd->footer(
      "Lock-step, one Tick stream: tick k carries line k's moves and time and each viewer's\n"
      "camera. Output: per viewer, the lines `voxvis replay` writes, {\"frame\", \"pvs\",\n"
      "\"wake\", \"stats\"}, frame = the tick; viewer 0's equal replay's. Moves need a\n"
      "simulation token.");
  return {cmd, [args] { return run_routed(&args->net, args->scene, [&] { return run_tick(*args); }); }};
}

}  // namespace voxvis::cli
