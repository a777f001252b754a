// loadgen_cmd.cpp — `voxvis loadgen`: many concurrent viewers of one scene,
// as View streams or (--tick) as one Tick stream, for capacity and latency
// measurements; with --metrics, the server's own CPU time per answer. The
// drivers are in loadgen_views.cpp and loadgen_ticks.cpp, their shared parts
// in loadgen.h.
#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include <unistd.h>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "cli.h"
#include "common.h"
#include "loadgen.h"
#include "options.h"
#include "output_file.h"
#include "server_usage.h"
#include "voxvis/client.h"
#include "voxvis/format.h"

namespace voxvis::cli {
namespace loadgen {

ProgressLine::ProgressLine(const LoadgenArgs& args, const Shared& shared)
    : args_(args), shared_(shared), tty_(::isatty(STDERR_FILENO) != 0),
      next_(shared.start + std::chrono::seconds(1)) {}

Clock::time_point ProgressLine::update(Clock::time_point now) {
  if (args_.quiet) return Clock::time_point::max();
  if (now < next_) return next_;
  const double elapsed = std::chrono::duration<double>(now - shared_.start).count();
  std::fprintf(stderr, "%sloadgen: %.1f/%g s, %d viewers%s, %s answers, p99 %.1f ms%s", tty_ ? "\r" : "",
               elapsed, args_.duration, args_.tick ? args_.viewers : shared_.open.load(),
               args_.tick ? " a tick" : "", with_commas(shared_.frames.load()).c_str(),
               shared_.latency.percentile_us(99.0) / 1000.0, tty_ ? "\x1b[K" : "\n");
  std::fflush(stderr);
  shown_ = true;
  while (next_ <= now) next_ += std::chrono::seconds(1);
  return next_;
}

void ProgressLine::finish() {
  if (!shown_) return;
  if (tty_) std::fputs("\r\x1b[K", stderr);
  std::fflush(stderr);
}

}  // namespace loadgen

namespace {

using loadgen::CameraSource;
using loadgen::Clock;
using loadgen::kMaxTickViewers;
using loadgen::Shared;

bool read_cameras(const std::string& path, std::vector<Camera>* cameras) {
  std::vector<FrameInput> frames;
  if (!read_frames(path, "loadgen", &frames)) return false;
  for (const FrameInput& f : frames) cameras->push_back(f.camera);
  return true;
}

/// Checks the numbers and the scene id, and parses the region flags into
/// `region`. On a bad one reports it and returns false.
bool check_loadgen_args(const LoadgenArgs& args, RegionOverride* region) {
  std::string message;
  if (!valid_scene_id(args.scene, &message)) {
    report(FormatError{"", 0, "--scene", message});
    return false;
  }
  if (args.viewers < 1 || args.viewers > 100'000) {
    report(FormatError{"", 0, "--viewers", "must be in [1, 100000], got " + std::to_string(args.viewers)});
    return false;
  }
  if (!std::isfinite(args.rate) || args.rate <= 0.0 || args.rate > 10'000.0) {
    report(FormatError{"", 0, "--rate", "must be in (0, 10000] frames per second per viewer"});
    return false;
  }
  if (!std::isfinite(args.duration) || args.duration <= 0.0 || args.duration > 7 * 86400.0) {
    report(FormatError{"", 0, "--duration", "must be in (0, 604800] seconds"});
    return false;
  }
  if (args.connections < 0 || args.connections > 1024) {
    report(FormatError{"", 0, "--connections",
                       "must be in [0, 1024] (0: one per 100 viewers), got " + std::to_string(args.connections)});
    return false;
  }
  if (args.tick && args.viewers > kMaxTickViewers) {
    report(FormatError{"", 0, "--viewers",
                       "with --tick, at most " + std::to_string(kMaxTickViewers) +
                           " (the server's limit of viewers in one tick), got " + std::to_string(args.viewers)});
    return false;
  }
  FormatError region_error;
  if (!parse_region_args(args.region, region, &region_error)) {
    report(region_error);
    return false;
  }
  return true;
}

/// The viewers' cameras: `cameras` (--frames), else an orbit inside the
/// scene's bounds. The server is asked for the scene either way (it must
/// exist). On error reports it, sets `*exit_code` and returns nullptr.
std::unique_ptr<CameraSource> loadgen_cameras(const LoadgenArgs& args, const client::Client& control,
                                              std::vector<Camera> cameras, const RegionOverride& region,
                                              int* exit_code) {
  v1::SceneInfo info;
  if (const grpc::Status st = control.get_scene_stats(args.scene, &info); !st.ok()) {
    *exit_code = report_status(st, args.net.server, "");
    return nullptr;
  }
  auto source = cameras.empty()
                    ? std::make_unique<CameraSource>(client::from_proto(info.bounds_min()),
                                                     client::from_proto(info.bounds_max()), args.viewers)
                    : std::make_unique<CameraSource>(std::move(cameras), args.viewers);
  source->set_region(region);
  return source;
}

/// Connections: gRPC multiplexes streams on one TCP connection per channel;
/// a few connections spread the load over the server's I/O threads.
int loadgen_connections(const LoadgenArgs& args) {
  return args.tick               ? 1
         : args.connections > 0 ? std::min(args.connections, args.viewers)
                                : (args.viewers + 99) / 100;
}

/// One client per connection, each on a channel of its own. On error
/// reports it, sets `*exit_code` and returns false.
bool open_loadgen_clients(const LoadgenArgs& args, int connections,
                          std::vector<std::unique_ptr<client::Client>>* clients, int* exit_code) {
  for (int c = 0; c < connections; ++c) {
    std::unique_ptr<client::Client> cl = open_client(args.net, exit_code, c + 1);
    if (cl == nullptr) return false;
    clients->push_back(std::move(cl));
  }
  return true;
}

/// The server's CPU time over the run (--metrics): its counters after the
/// run less those before, over the answers it counted for the scene.
struct ServerCpu {
  bool scraped = false;  ///< The counters after the run were read.
  std::string error;     ///< Why not.
  double answers = 0.0, cpu_s = 0.0, engine_s = 0.0;
  bool per_answer() const { return scraped && answers > 0.0; }
};

/// Reads the counters after the run: all answers are in (the streams ended).
ServerCpu server_cpu_over_run(const LoadgenArgs& args, const ServerUsage& before) {
  ServerUsage after;
  ServerCpu cpu;
  cpu.scraped = !args.metrics.empty() && scrape_server_usage(args.metrics, args.scene, &after, &cpu.error);
  cpu.answers = after.frames - before.frames;
  cpu.cpu_s = after.cpu_seconds - before.cpu_seconds;
  cpu.engine_s = after.engine_seconds - before.engine_seconds;
  return cpu;
}

/// The run's figures, read from the shared state once the streams ended.
struct LoadgenFigures {
  std::uint64_t answers = 0;
  double answers_per_s = 0.0;
  double p50 = 0.0, p99 = 0.0, max_ms = 0.0;  ///< Latency, ms.
  std::uint64_t answered_streams = 0;
  int streams = 0;
  double first_p50 = 0.0, first_max = 0.0;  ///< First answer, ms.
  double gap_p99 = 0.0, gap_max = 0.0;      ///< Answer gaps, ms.
  std::string errors_text;
  nlohmann::json errors_json = nlohmann::json::object();
};

LoadgenFigures loadgen_figures(const LoadgenArgs& args, const Shared& shared) {
  LoadgenFigures f;
  f.answers = shared.frames.load();
  // Over the time answers took to come, not the sending time: a saturated
  // server still answers queued frames after the end, and those must not
  // count as if they had come within the duration.
  const double answer_seconds = static_cast<double>(shared.last_answer_ns.load()) * 1e-9;
  f.answers_per_s = answer_seconds > 0.0 ? static_cast<double>(f.answers) / answer_seconds : 0.0;
  f.p50 = shared.latency.percentile_us(50.0) / 1000.0;
  f.p99 = shared.latency.percentile_us(99.0) / 1000.0;
  f.max_ms = shared.latency.max_us() / 1000.0;
  f.answered_streams = shared.first_answer.count();
  f.streams = args.tick ? 1 : args.viewers;
  f.first_p50 = shared.first_answer.percentile_us(50.0) / 1000.0;
  f.first_max = shared.first_answer.max_us() / 1000.0;
  f.gap_p99 = shared.gap.percentile_us(99.0) / 1000.0;
  f.gap_max = shared.gap.max_us() / 1000.0;
  for (const auto& [name, count] : shared.errors) {
    if (!f.errors_text.empty()) f.errors_text += ", ";
    f.errors_text += name + " " + std::to_string(count);
    f.errors_json[name] = count;
  }
  if (shared.answer_errors.load() > 0) {
    if (!f.errors_text.empty()) f.errors_text += ", ";
    f.errors_text += with_commas(shared.answer_errors.load()) + " viewer entries failed";
  }
  if (f.errors_text.empty()) f.errors_text = "none";
  if (shared.cancelled_at_end > 0) {
    f.errors_text += " (" + std::to_string(shared.cancelled_at_end) + " streams cancelled after the end)";
  }
  return f;
}

/// The report on stdout.
void print_loadgen_report(const LoadgenArgs& args, int connections, const LoadgenFigures& f, const Shared& shared,
                          const ServerCpu& cpu) {
  std::printf("loadgen: %d viewers%s at %g Hz for %g s on scene %s (%s, %d connection%s)\n",
              args.viewers, args.tick ? " a tick" : "", args.rate, args.duration, args.scene.c_str(),
              args.delta ? "PVS_DELTA" : "PVS_FULL", connections, connections == 1 ? "" : "s");
  if (args.tick) {
    std::printf("  ticks answered   %s of %s sent\n", with_commas(shared.ticks_answered.load()).c_str(),
                with_commas(shared.ticks_sent.load()).c_str());
  }
  std::printf(
      "  answers          %s (%.1f per second)\n"
      "  latency ms       p50 %.3f, p99 %.3f, max %.3f%s\n"
      "  first answer ms  p50 %.3f, max %.3f (%s of %d streams answered)\n"
      "  answer gaps ms   p99 %.3f, max %.3f\n"
      "  server skipped   %s %s\n"
      "  send skipped     %s %s\n"
      "  errors           %s\n",
      with_commas(f.answers).c_str(), f.answers_per_s, f.p50, f.p99, f.max_ms, args.tick ? " (a tick)" : "",
      f.first_p50, f.first_max, with_commas(f.answered_streams).c_str(), f.streams, f.gap_p99, f.gap_max,
      with_commas(shared.server_skipped.load()).c_str(), args.tick ? "ticks" : "frames",
      with_commas(shared.send_skipped.load()).c_str(), args.tick ? "ticks" : "frames", f.errors_text.c_str());
  if (cpu.per_answer()) {
    std::printf("  server CPU       %.1f us an answer (%.1f us of it the engine's frame), %.3f s in all\n",
                1e6 * cpu.cpu_s / cpu.answers, 1e6 * cpu.engine_s / cpu.answers, cpu.cpu_s);
  } else if (!args.metrics.empty()) {
    std::printf("  server CPU       unknown: %s\n", cpu.scraped ? "the server counted no answer" : cpu.error.c_str());
  }
  std::fflush(stdout);
}

/// The report as --json writes it.
nlohmann::json loadgen_json(const LoadgenArgs& args, const LoadgenFigures& f, const Shared& shared,
                            const ServerCpu& cpu) {
  nlohmann::json j = {
      {"mode", args.tick ? "tick" : "view"},
      {"viewers", args.viewers},
      {"rate_hz", args.rate},
      {"duration_s", args.duration},
      {"frames", f.answers},
      {"fps", f.answers_per_s},
      {"answers_per_s", f.answers_per_s},
      {"p50_ms", f.p50},
      {"p99_ms", f.p99},
      {"max_ms", f.max_ms},
      {"streams_answered", f.answered_streams},
      {"first_answer_p50_ms", f.first_p50},
      {"first_answer_max_ms", f.first_max},
      {"gap_p99_ms", f.gap_p99},
      {"gap_max_ms", f.gap_max},
      {"server_skipped", shared.server_skipped.load()},
      {"send_skipped", shared.send_skipped.load()},
      {"errors", f.errors_json},
  };
  if (args.tick) {
    j["ticks_sent"] = shared.ticks_sent.load();
    j["ticks_answered"] = shared.ticks_answered.load();
    j["answer_errors"] = shared.answer_errors.load();
  }
  if (cpu.per_answer()) {
    // Over the server's own count of answers for the scene (every client's).
    j["server_answers"] = cpu.answers;
    j["server_cpu_s"] = cpu.cpu_s;
    j["server_cpu_s_per_answer"] = cpu.cpu_s / cpu.answers;
    j["server_engine_s_per_answer"] = cpu.engine_s / cpu.answers;
    j["server_overhead_s_per_answer"] = (cpu.cpu_s - cpu.engine_s) / cpu.answers;
  }
  return j;
}

}  // namespace

int run_loadgen(const LoadgenArgs& args) {
  RegionOverride region;
  if (!check_loadgen_args(args, &region)) return kExitError;
  std::vector<Camera> cameras;
  if (!args.frames.empty() && !read_cameras(args.frames, &cameras)) return kExitError;
  // Open the report file now, so that a bad path fails before the run.
  std::string message;
  OutputFile json_out;
  if (!args.json.empty() && !json_out.open(args.json, &message)) {
    return report(FormatError{args.json, 0, "", message});
  }
  // The scene: exists, reachable, and its bounds for the orbit.
  int code = kExitOk;
  const std::unique_ptr<client::Client> control = open_client(args.net, &code);
  if (control == nullptr) return code;
  const std::unique_ptr<CameraSource> source = loadgen_cameras(args, *control, std::move(cameras), region, &code);
  if (source == nullptr) return code;

  // The server's counters before (--metrics): its CPU time per answer is
  // the difference over the run divided by the answers.
  ServerUsage usage_before;
  if (!args.metrics.empty() && !scrape_server_usage(args.metrics, args.scene, &usage_before, &message)) {
    return report(FormatError{"", 0, "--metrics", message});
  }
  const int connections = loadgen_connections(args);
  std::vector<std::unique_ptr<client::Client>> clients;
  if (!open_loadgen_clients(args, connections, &clients, &code)) return code;

  // Shared state and reactors live on the heap: if some stream never ends
  // (it should not, cancelled), they are leaked rather than freed under it.
  auto shared = std::make_unique<Shared>();
  shared->address = args.net.server;
  shared->start = Clock::now();
  const bool ended = args.tick ? loadgen::drive_ticks(args, *source, *clients.front(), *shared)
                               : loadgen::drive_views(args, *source, clients, *shared);
  if (!ended) {
    (void)shared.release();
    std::fprintf(stderr, "voxvis: internal error: some %s streams did not end after cancellation\n",
                 args.tick ? "Tick" : "View");
    return kExitInternal;
  }

  const ServerCpu cpu = server_cpu_over_run(args, usage_before);
  const LoadgenFigures figures = loadgen_figures(args, *shared);
  print_loadgen_report(args, connections, figures, *shared, cpu);
  if (!args.json.empty()) {
    const std::string text = loadgen_json(args, figures, *shared, cpu).dump(2) + "\n";
    if (!json_out.write(text) || !json_out.commit(&message)) {
      if (message.empty()) message = std::string("cannot write: ") + std::strerror(errno);
      return report(FormatError{args.json, 0, "", message});
    }
  }

  if (!shared->first_error.empty()) {
    std::fprintf(stderr, "voxvis: error: %s\n", shared->first_error.c_str());
    return kExitError;
  }
  if (!args.metrics.empty() && !cpu.scraped) {
    std::fprintf(stderr, "voxvis: error: --metrics: %s\n", cpu.error.c_str());
    return kExitError;
  }
  return kExitOk;
}

Command add_loadgen_command(CLI::App& app) {
  auto args = std::make_shared<LoadgenArgs>();
  CLI::App* cmd = app.add_subcommand("loadgen", "Load a server with many concurrent viewers and report latencies.");
  add_net_options(cmd, &args->net);
  cmd->add_option("--scene", args->scene, "Scene id on the server")->required()->type_name("ID");
  cmd->add_option("--viewers", args->viewers, "Concurrent View streams (with --tick: viewers in each tick)")
      ->required()
      ->type_name("N");
  cmd->add_option("--rate", args->rate, "Frames per second per viewer (with --tick: ticks per second)")
      ->required()
      ->type_name("HZ");
  cmd->add_option("--duration", args->duration, "Seconds of sending")->required()->type_name("SECONDS");
  cmd->add_option("--frames", args->frames,
                  "Cameras to loop over, each viewer from its own offset (default: an "
                  "orbit inside the scene's bounds)")
      ->type_name("FILE");
  cmd->add_flag("--delta", args->delta, "Ask for PVS deltas");
  add_region_options(cmd, &args->region);
  cmd->add_option("--json", args->json, "Also write the report as JSON")->type_name("FILE");
  cmd->add_option("--connections", args->connections,
                  "TCP connections the streams are spread over (default: one per 100 "
                  "viewers)")
      ->type_name("N");
  cmd->add_flag("--tick", args->tick,
                "One Tick stream whose every request carries all viewers' cameras (a game "
                "server's tick), instead of a View stream per viewer");
  cmd->add_option("--metrics", args->metrics,
                  "The server's metrics address (its --metrics): report its CPU time per "
                  "answer, and the engine's part of it")
      ->type_name("HOST:PORT");
  cmd->add_flag("-q,--quiet", args->quiet, "No progress line on stderr");
  cmd->footer(
      "Latency: from sending a frame to receiving the answer carrying its number;\n"
      "frames per second: answers over the time from the start to the last answer;\n"
      "first answer: from a stream's first send to its first answer; answer gaps:\n"
      "between two answers of one stream (the first gap is the first answer's wait).\n"
      "A tick that finds the viewer's previous write still outstanding is skipped\n"
      "(\"send skipped\"). With --tick, latency is a whole tick's, answers count one\n"
      "per viewer answered, and the server's skips are ticks replaced by newer ones.\n"
      "With --metrics, the server's CPU seconds (process_cpu_seconds_total) and the\n"
      "engine's (voxvis_frame_engine_seconds) over the run, per answer it counted for\n"
      "the scene. Report on stdout; exit 2 if a stream ended with an error.");
  return {cmd, [args] { return run_routed(&args->net, args->scene, [&] { return run_loadgen(*args); }); }};
}

}  // namespace voxvis::cli
