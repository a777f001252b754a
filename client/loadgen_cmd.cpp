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

#include <nlohmann/json.hpp>

#include "cli.h"
#include "common.h"
#include "loadgen.h"
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

}  // namespace

int run_loadgen(const LoadgenArgs& args) {
  // Arguments.
  std::string message;
  if (!valid_scene_id(args.scene, &message)) return report(FormatError{"", 0, "--scene", message});
  if (args.viewers < 1 || args.viewers > 100'000) {
    return report(FormatError{"", 0, "--viewers", "must be in [1, 100000], got " + std::to_string(args.viewers)});
  }
  if (!std::isfinite(args.rate) || args.rate <= 0.0 || args.rate > 10'000.0) {
    return report(FormatError{"", 0, "--rate", "must be in (0, 10000] frames per second per viewer"});
  }
  if (!std::isfinite(args.duration) || args.duration <= 0.0 || args.duration > 7 * 86400.0) {
    return report(FormatError{"", 0, "--duration", "must be in (0, 604800] seconds"});
  }
  if (args.connections < 0 || args.connections > 1024) {
    return report(FormatError{"", 0, "--connections", "must be in [0, 1024] (0: one per 100 viewers), got " +
                                                         std::to_string(args.connections)});
  }
  if (args.tick && args.viewers > kMaxTickViewers) {
    return report(FormatError{"", 0, "--viewers",
                              "with --tick, at most " + std::to_string(kMaxTickViewers) +
                                  " (the server's limit of viewers in one tick), got " + std::to_string(args.viewers)});
  }
  RegionOverride region;
  FormatError region_error;
  if (!parse_region_args(args.region, &region, &region_error)) return report(region_error);
  std::vector<Camera> cameras;
  if (!args.frames.empty() && !read_cameras(args.frames, &cameras)) return kExitError;
  // Open the report file now, so that a bad path fails before the run.
  OutputFile json_out;
  if (!args.json.empty() && !json_out.open(args.json, &message)) {
    return report(FormatError{args.json, 0, "", message});
  }

  // The scene: exists, reachable, and its bounds for the orbit.
  int code = kExitOk;
  const std::unique_ptr<client::Client> control = open_client(args.net, &code);
  if (control == nullptr) return code;
  v1::SceneInfo info;
  if (const grpc::Status st = control->get_scene_stats(args.scene, &info); !st.ok()) {
    return report_status(st, args.net.server, "");
  }
  CameraSource source =
      cameras.empty()
          ? CameraSource(client::from_proto(info.bounds_min()), client::from_proto(info.bounds_max()),
                         args.viewers)
          : CameraSource(std::move(cameras), args.viewers);
  source.set_region(region);

  // The server's counters before (--metrics): its CPU time per answer is
  // the difference over the run divided by the answers.
  ServerUsage usage_before;
  if (!args.metrics.empty() && !scrape_server_usage(args.metrics, args.scene, &usage_before, &message)) {
    return report(FormatError{"", 0, "--metrics", message});
  }

  // Connections: gRPC multiplexes streams on one TCP connection per channel;
  // a few connections spread the load over the server's I/O threads.
  const int connections = args.tick               ? 1
                          : args.connections > 0 ? std::min(args.connections, args.viewers)
                                                 : (args.viewers + 99) / 100;
  std::vector<std::unique_ptr<client::Client>> clients;
  for (int c = 0; c < connections; ++c) {
    std::unique_ptr<client::Client> cl = open_client(args.net, &code, c + 1);
    if (cl == nullptr) return code;
    clients.push_back(std::move(cl));
  }

  // Shared state and reactors live on the heap: if some stream never ends
  // (it should not, cancelled), they are leaked rather than freed under it.
  auto shared = std::make_unique<Shared>();
  shared->address = args.net.server;
  shared->start = Clock::now();
  const bool ended = args.tick ? loadgen::drive_ticks(args, source, *clients.front(), *shared)
                               : loadgen::drive_views(args, source, clients, *shared);
  if (!ended) {
    (void)shared.release();
    std::fprintf(stderr, "voxvis: internal error: some %s streams did not end after cancellation\n",
                 args.tick ? "Tick" : "View");
    return kExitInternal;
  }

  // The server's counters after: all answers are in (the streams ended).
  ServerUsage usage_after;
  std::string usage_error;
  const bool usage = !args.metrics.empty() && scrape_server_usage(args.metrics, args.scene, &usage_after, &usage_error);
  const double server_answers = usage_after.frames - usage_before.frames;
  const double cpu_s = usage_after.cpu_seconds - usage_before.cpu_seconds;
  const double engine_s = usage_after.engine_seconds - usage_before.engine_seconds;
  const bool per_answer = usage && server_answers > 0.0;

  // The report.
  const std::uint64_t answers = shared->frames.load();
  // Over the time answers took to come, not the sending time: a saturated
  // server still answers queued frames after the end, and those must not
  // count as if they had come within the duration.
  const double answer_seconds = static_cast<double>(shared->last_answer_ns.load()) * 1e-9;
  const double answers_per_s = answer_seconds > 0.0 ? static_cast<double>(answers) / answer_seconds : 0.0;
  const double p50 = shared->latency.percentile_us(50.0) / 1000.0;
  const double p99 = shared->latency.percentile_us(99.0) / 1000.0;
  const double max_ms = shared->latency.max_us() / 1000.0;
  const std::uint64_t answered_streams = shared->first_answer.count();
  const int streams = args.tick ? 1 : args.viewers;
  const double first_p50 = shared->first_answer.percentile_us(50.0) / 1000.0;
  const double first_max = shared->first_answer.max_us() / 1000.0;
  const double gap_p99 = shared->gap.percentile_us(99.0) / 1000.0;
  const double gap_max = shared->gap.max_us() / 1000.0;
  std::string errors_text;
  nlohmann::json errors_json = nlohmann::json::object();
  for (const auto& [name, count] : shared->errors) {
    if (!errors_text.empty()) errors_text += ", ";
    errors_text += name + " " + std::to_string(count);
    errors_json[name] = count;
  }
  if (shared->answer_errors.load() > 0) {
    if (!errors_text.empty()) errors_text += ", ";
    errors_text += with_commas(shared->answer_errors.load()) + " viewer entries failed";
  }
  if (errors_text.empty()) errors_text = "none";
  if (shared->cancelled_at_end > 0) {
    errors_text += " (" + std::to_string(shared->cancelled_at_end) + " streams cancelled after the end)";
  }
  std::printf("loadgen: %d viewers%s at %g Hz for %g s on scene %s (%s, %d connection%s)\n",
              args.viewers, args.tick ? " a tick" : "", args.rate, args.duration, args.scene.c_str(),
              args.delta ? "PVS_DELTA" : "PVS_FULL", connections, connections == 1 ? "" : "s");
  if (args.tick) {
    std::printf("  ticks answered   %s of %s sent\n", with_commas(shared->ticks_answered.load()).c_str(),
                with_commas(shared->ticks_sent.load()).c_str());
  }
  std::printf(
      "  answers          %s (%.1f per second)\n"
      "  latency ms       p50 %.3f, p99 %.3f, max %.3f%s\n"
      "  first answer ms  p50 %.3f, max %.3f (%s of %d streams answered)\n"
      "  answer gaps ms   p99 %.3f, max %.3f\n"
      "  server skipped   %s %s\n"
      "  send skipped     %s %s\n"
      "  errors           %s\n",
      with_commas(answers).c_str(), answers_per_s, p50, p99, max_ms, args.tick ? " (a tick)" : "", first_p50,
      first_max, with_commas(answered_streams).c_str(), streams, gap_p99, gap_max,
      with_commas(shared->server_skipped.load()).c_str(), args.tick ? "ticks" : "frames",
      with_commas(shared->send_skipped.load()).c_str(), args.tick ? "ticks" : "frames", errors_text.c_str());
  if (per_answer) {
    std::printf("  server CPU       %.1f us an answer (%.1f us of it the engine's frame), %.3f s in all\n",
                1e6 * cpu_s / server_answers, 1e6 * engine_s / server_answers, cpu_s);
  } else if (!args.metrics.empty()) {
    std::printf("  server CPU       unknown: %s\n", usage ? "the server counted no answer" : usage_error.c_str());
  }
  std::fflush(stdout);

  if (!args.json.empty()) {
    nlohmann::json report_json = {
        {"mode", args.tick ? "tick" : "view"},
        {"viewers", args.viewers},
        {"rate_hz", args.rate},
        {"duration_s", args.duration},
        {"frames", answers},
        {"fps", answers_per_s},
        {"answers_per_s", answers_per_s},
        {"p50_ms", p50},
        {"p99_ms", p99},
        {"max_ms", max_ms},
        {"streams_answered", answered_streams},
        {"first_answer_p50_ms", first_p50},
        {"first_answer_max_ms", first_max},
        {"gap_p99_ms", gap_p99},
        {"gap_max_ms", gap_max},
        {"server_skipped", shared->server_skipped.load()},
        {"send_skipped", shared->send_skipped.load()},
        {"errors", errors_json},
    };
    if (args.tick) {
      report_json["ticks_sent"] = shared->ticks_sent.load();
      report_json["ticks_answered"] = shared->ticks_answered.load();
      report_json["answer_errors"] = shared->answer_errors.load();
    }
    if (per_answer) {
      // Over the server's own count of answers for the scene (every client's).
      report_json["server_answers"] = server_answers;
      report_json["server_cpu_s"] = cpu_s;
      report_json["server_cpu_s_per_answer"] = cpu_s / server_answers;
      report_json["server_engine_s_per_answer"] = engine_s / server_answers;
      report_json["server_overhead_s_per_answer"] = (cpu_s - engine_s) / server_answers;
    }
    const std::string text = report_json.dump(2) + "\n";
    if (!json_out.write(text) || !json_out.commit(&message)) {
      if (message.empty()) message = std::string("cannot write: ") + std::strerror(errno);
      return report(FormatError{args.json, 0, "", message});
    }
  }

  if (!shared->first_error.empty()) {
    std::fprintf(stderr, "voxvis: error: %s\n", shared->first_error.c_str());
    return kExitError;
  }
  if (!args.metrics.empty() && !usage) {
    std::fprintf(stderr, "voxvis: error: --metrics: %s\n", usage_error.c_str());
    return kExitError;
  }
  return kExitOk;
}

}  // namespace voxvis::cli
