// verify_merge_cmd.cpp — `voxvis verify-merge`: the slices of a verification
// split over many workers (`voxvis verify --first-frame/--frame-count`, one
// per pod of an indexed Job: deploy/k8s/verify-job.yaml) joined into the
// whole job's output, checked to cover the recording once, and summarised
// as `verify` summarises one run.
#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "cli.h"
#include "common.h"
#include "output_file.h"

namespace voxvis::cli {
namespace {

struct Slice {
  std::string path;
  std::vector<std::string> lines;
  std::int64_t first = -1;  // Its first frame; -1 when empty.
};

/// Reads one slice file: every line a verify line whose frames follow one
/// another. On error reports it (file:line) and returns false.
bool read_slice(const std::string& path, Slice* slice, int* code) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    *code = report(FormatError{path, 0, "", "cannot open"});
    return false;
  }
  slice->path = path;
  std::string line;
  int line_no = 0;
  std::int64_t expect = -1;
  while (std::getline(in, line)) {
    ++line_no;
    if (blank(line)) continue;
    const nlohmann::json j = nlohmann::json::parse(line, nullptr, false);
    if (!j.is_object() || !j.contains("frame") || !j["frame"].is_number_integer() || !j.contains("missed") ||
        !j["missed"].is_array() || !j.contains("visible") || !j["visible"].is_array()) {
      *code = report(FormatError{path, line_no, "", "not a `voxvis verify` output line"});
      return false;
    }
    const std::int64_t frame = j["frame"].get<std::int64_t>();
    if (expect >= 0 && frame != expect) {
      *code = report(FormatError{path, line_no, "frame",
                                 "is " + std::to_string(frame) + " after " + std::to_string(expect - 1) +
                                     " (a slice's frames follow one another)"});
      return false;
    }
    if (expect < 0) slice->first = frame;
    expect = frame + 1;
    slice->lines.push_back(line);
  }
  if (in.bad()) {
    *code = report(FormatError{path, line_no, "", "cannot read"});
    return false;
  }
  return true;
}

}  // namespace

int run_verify_merge(const VerifyMergeArgs& args) {
  int code = kExitOk;
  std::vector<Slice> slices(args.slices.size());
  for (std::size_t i = 0; i < args.slices.size(); ++i)
    if (!read_slice(args.slices[i], &slices[i], &code)) return code;
  // In frame order whatever order the shell's glob gave.
  std::erase_if(slices, [](const Slice& s) { return s.lines.empty(); });
  if (slices.empty()) return report(FormatError{"", 0, "", "no frame in any slice (" + std::to_string(args.slices.size()) +
                                                            " files): nothing to merge"});
  std::sort(slices.begin(), slices.end(), [](const Slice& a, const Slice& b) { return a.first < b.first; });
  std::int64_t next = slices.front().first;
  if (args.frames >= 0 && next != 0)
    return report(FormatError{slices.front().path, 0, "", "starts at frame " + std::to_string(next) +
                                                              ": no slice has frames 0 to " + std::to_string(next - 1)});
  for (const Slice& s : slices) {
    if (s.first != next) {
      return report(FormatError{s.path, 0, "",
                                s.first > next ? "frames " + std::to_string(next) + " to " + std::to_string(s.first - 1) +
                                                     " are in no slice"
                                               : "frame " + std::to_string(s.first) + " is in two slices"});
    }
    next = s.first + static_cast<std::int64_t>(s.lines.size());
  }
  if (args.frames >= 0 && next != args.frames) {
    return report(FormatError{"", 0, "--frames",
                              "the slices cover frames 0 to " + std::to_string(next - 1) + " of " +
                                  std::to_string(args.frames)});
  }

  OutputFile out;
  std::string message;
  if (!out.open(args.out, &message)) return report(FormatError{args.out, 0, "", message});
  std::uint64_t frames = 0, missed = 0, frames_missed = 0, edge_only = 0, visible = 0, pvs = 0;
  std::vector<double> draw_ms;
  for (const Slice& s : slices) {
    for (const std::string& line : s.lines) {
      const nlohmann::json j = nlohmann::json::parse(line);
      const std::size_t m = j["missed"].size();
      ++frames;
      missed += m;
      frames_missed += m > 0 ? 1 : 0;
      visible += j["visible"].size();
      if (j.contains("edge_only") && j["edge_only"].is_array()) edge_only += j["edge_only"].size();
      if (j.contains("pvs_size") && j["pvs_size"].is_number_unsigned()) pvs += j["pvs_size"].get<std::uint64_t>();
      if (j.contains("stats") && j["stats"].contains("draw_ms") && j["stats"]["draw_ms"].is_number())
        draw_ms.push_back(j["stats"]["draw_ms"].get<double>());
      if (m > 0)
        std::fprintf(stderr, "voxvis: MISS: frame %lld: %zu visible object(s) not in the PVS: %s\n",
                     static_cast<long long>(j["frame"].get<std::int64_t>()), m, j["missed"].dump().c_str());
      if (!out.write(line) || !out.write("\n")) return report(FormatError{out.path(), 0, "", "cannot write"});
    }
  }
  if (!out.commit(&message)) return report(FormatError{out.path(), 0, "", message});
  const Spread d = spread(draw_ms);
  std::fprintf(stderr,
               "voxvis: %zu slices, %llu frames: %llu missed object-frames in %llu frames; %llu edge-only "
               "sightings dismissed; visible %llu, PVS %llu, tightness %.3f; draw ms median %.2f p99 %.2f\n",
               slices.size(), static_cast<unsigned long long>(frames), static_cast<unsigned long long>(missed),
               static_cast<unsigned long long>(frames_missed), static_cast<unsigned long long>(edge_only),
               static_cast<unsigned long long>(visible), static_cast<unsigned long long>(pvs),
               visible ? static_cast<double>(pvs) / static_cast<double>(visible) : 0.0, d.median, d.p99);
  return missed > 0 ? kExitMissed : kExitOk;
}

Command add_verify_merge_command(CLI::App& app) {
  auto args = std::make_shared<VerifyMergeArgs>();
  CLI::App* cmd = app.add_subcommand(
      "verify-merge", "Join the slices of a verification split over workers, check them, summarise.");
  cmd->add_option("slices", args->slices, "`voxvis verify --out` files of the slices, any order")
      ->required()
      ->type_name("SLICE");
  cmd->add_option("--out", args->out, "The joined output (JSON Lines); default stdout")->type_name("FILE");
  cmd->add_option("--frames", args->frames, "Frames the slices must cover, 0 to N-1 (a lost slice is an error)")
      ->check(CLI::NonNegativeNumber)
      ->type_name("N");
  cmd->footer(
      "The slices are sorted by their first frame; a gap or an overlap is an error naming\n"
      "the file. The summary (stderr) counts as `verify`'s: missed object-frames, edge-only\n"
      "sightings dismissed, visible, PVS, tightness. Exit 3 when a frame has a miss.");
  return {cmd, [args] { return run_verify_merge(*args); }};
}

}  // namespace voxvis::cli
