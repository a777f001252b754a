// replay.cpp — `voxvis replay`: a scene file and a frames file in, one PVS
// line per frame out.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iterator>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include <unistd.h>

#include <CLI/CLI.hpp>

#include "cli.h"
#include "common.h"
#include "model_loader.h"
#include "options.h"
#include "output_file.h"
#include "voxvis/format.h"
#include "voxvis/scene.h"

namespace voxvis::cli {

int report(const FormatError& error) {
  std::fprintf(stderr, "voxvis: error: %s\n", error.str().c_str());
  return kExitError;
}

bool parse_grid_arg(const std::string& text, int max_per_axis, int out[3], std::string* message) {
  const auto bad = [&](const std::string& why) {
    *message = why + " (expected NX,NY,NZ: three integers >= 1, for example 64,32,64), got '" +
               text + "'";
    return false;
  };
  std::size_t pos = 0;
  for (int axis = 0; axis < 3; ++axis) {
    if (axis > 0) {
      if (pos >= text.size() || text[pos] != ',') return bad("malformed value");
      ++pos;
    }
    const std::size_t start = pos;
    while (pos < text.size() && text[pos] >= '0' && text[pos] <= '9') ++pos;
    if (pos == start) {
      if (pos < text.size() && text[pos] == '-') return bad("resolutions must be >= 1");
      return bad("malformed value");
    }
    // Compare as digits first: values beyond int range are simply too large.
    std::string digits = text.substr(start, pos - start);
    digits.erase(0, std::min(digits.find_first_not_of('0'), digits.size() - 1));
    const std::string limit = std::to_string(max_per_axis);
    if (digits.size() > limit.size() || (digits.size() == limit.size() && digits > limit)) {
      *message = "resolution " + digits + " exceeds the limit of " + limit +
                 " voxels per axis, got '" + text + "'";
      return false;
    }
    const int v = std::stoi(digits);
    if (v < 1) return bad("resolutions must be >= 1");
    out[axis] = v;
  }
  if (pos != text.size()) return bad("malformed value");
  return true;
}

bool load_scene(const EngineArgs& args, std::string* text, SceneDesc* desc, SceneOptions* options,
                int* exit_code) {
  FormatError error;
  if (!read_file(args.scene, text, &error) ||
      !parse_scene(*text, args.scene, desc, &error, scene_read_options(args.scene))) {
    *exit_code = report(error);
    return false;
  }
  if (args.tbv_period) options->tbv_period = *args.tbv_period;
  options->occlusion_buffer = args.occlusion_buffer;
  if (!args.grid.empty()) {
    int res[3] = {0, 0, 0};
    std::string message;
    if (!parse_grid_arg(args.grid, options->max_resolution, res, &message)) {
      *exit_code = report(FormatError{"", 0, "--grid", message});
      return false;
    }
    desc->grid = glm::ivec3(res[0], res[1], res[2]);
  }
  return true;
}

bool build_scene(const EngineArgs& args, std::string* text, const SceneDesc& desc, const SceneOptions& options,
                 std::unique_ptr<Scene>* scene, int* exit_code) {
  if (const Status st = Scene::create(desc, options, scene); !st.ok) {
    std::string what = st.message;
    if (!args.grid.empty() && st.field.rfind("grid", 0) == 0) what += " (resolution from --grid)";
    // A --grid resolution has no line in the scene file.
    const bool from_flag = (!args.grid.empty() && st.field.rfind("grid", 0) == 0) ||
                           st.field == "occlusion_buffer";
    const int line = from_flag || st.field.empty() ? 0 : scene_field_line(*text, st.field);
    *exit_code = report(FormatError{args.scene, line, st.field, what});
    return false;
  }
  if (*scene == nullptr) {
    *exit_code = report(FormatError{args.scene, 0, "", "scene creation failed"});
    return false;
  }
  text->clear();  // Kept until now so that engine errors can name a line.
  text->shrink_to_fit();
  return true;
}

int run_replay(const ReplayArgs& args) {
  // The scene: parse, apply --grid, build.
  std::string text;
  SceneDesc desc;
  SceneOptions options;
  int code = kExitOk;
  RegionOverride region;
  FormatError region_error;
  if (!parse_region_args(args.region, &region, &region_error)) return report(region_error);
  if (!load_scene(args.engine, &text, &desc, &options, &code)) return code;
  // Open the frames and the output before the (possibly slow) scene build,
  // so that a bad path fails at once.
  std::ifstream frames(args.frames, std::ios::binary);
  if (!frames) {
    return report(FormatError{args.frames, 0, "", std::string("cannot open: ") + std::strerror(errno)});
  }
  OutputFile out;
  std::string message;
  if (!out.open(args.out, &message)) return report(FormatError{args.out, 0, "", message});

  std::unique_ptr<Scene> scene;
  if (!build_scene(args.engine, &text, desc, options, &scene, &code)) return code;
  const ViewerId viewer = scene->add_viewer();
  FormatError error;

  Scratch scratch;
  FrameInput frame;
  FrameResult result;
  MoveReport moves;
  std::vector<double> times;
  double pvs_total = 0.0;
  std::size_t too_fast = 0;
  std::size_t index = 0;
  int line_no = 0;
  std::string line;
  std::string out_line;
  Progress progress(!args.quiet && ::isatty(STDERR_FILENO) != 0);

  while (std::getline(frames, line)) {
    ++line_no;
    if (blank(line)) continue;
    if (!parse_frame_line(line, args.frames, line_no, &frame, &error)) {
      progress.finish();
      return report(error);
    }
    region.apply(&frame.camera);
    if (!frame.moves.empty()) {
      moves = MoveReport{};
      if (const Status st = scene->apply_moves(frame.t, frame.moves, &moves); !st.ok) {
        progress.finish();
        return report(FormatError{args.frames, line_no, st.field, st.message});
      }
      too_fast += moves.too_fast.size();
    }
    if (const Status st = scene->frame(viewer, frame.camera, frame.t, scratch, &result); !st.ok) {
      progress.finish();
      return report(FormatError{args.frames, line_no, st.field, st.message});
    }
    out_line = result_to_json(index, result);
    out_line += '\n';
    if (!out.write(out_line)) {
      progress.finish();
      return report(FormatError{out.path(), 0, "", std::string("cannot write: ") + std::strerror(errno)});
    }
    times.push_back(result.stats.time_us);
    pvs_total += static_cast<double>(result.pvs.size());
    ++index;
    progress.update(index);
  }
  if (frames.bad()) {
    progress.finish();
    return report(FormatError{args.frames, line_no, "", std::string("cannot read: ") + std::strerror(errno)});
  }
  progress.finish();
  if (!out.commit(&message)) return report(FormatError{out.path(), 0, "", message});

  if (!args.quiet) {
    const double wall = progress.elapsed();
    const Spread sp = spread(times);
    const double n = static_cast<double>(std::max<std::size_t>(times.size(), 1));
    std::fprintf(stderr,
                 "voxvis: %zu frames in %.2f s; time_us mean %.1f, median %.1f, p99 %.1f; "
                 "mean PVS %.1f objects; too-fast moves %zu\n",
                 index, wall, sp.mean, sp.median, sp.p99, pvs_total / n, too_fast);
  }
  return kExitOk;
}

Command add_replay_command(CLI::App& app) {
  auto args = std::make_shared<ReplayArgs>();
  CLI::App* cmd = app.add_subcommand(
      "replay",
      "Replay a frames file against a scene and write one PVS line per frame.");
  cmd->add_option("--scene", args->engine.scene, "Scene file (JSON, format voxvis-scene/1)")
      ->required()
      ->type_name("FILE");
  cmd->add_option("--frames", args->frames, "Frames file (JSON Lines: one camera and optional moves per line)")
      ->required()
      ->type_name("FILE");
  cmd->add_option("--grid", args->engine.grid,
                  "Grid resolution overriding the scene's, voxels per axis (e.g. 64,32,64)")
      ->type_name("NX,NY,NZ");
  cmd->add_option("--out", args->out, "Output file (JSON Lines), written whole or not at all; default stdout")
      ->type_name("FILE");
  const auto tbv = add_tbv_period_option(
      cmd, "Fixed validity period of temporal bounding volumes, seconds (default: adaptive)");
  cmd->add_option("--occlusion-buffer", args->engine.occlusion_buffer,
                  "Width in pixels of the conservative occlusion buffer (8..4096, "
                  "or 0: off; default 160)")
      ->type_name("PIXELS");
  add_region_options(cmd, &args->region);
  cmd->add_flag("-q,--quiet", args->quiet, "No progress line and no summary on stderr");
  cmd->footer(
      "Output: one line per frame, {\"frame\", \"pvs\", \"wake\", \"stats\"}; ids ascending.\n"
      "Progress (on a terminal) and a timing summary go to stderr unless --quiet.");
  return {cmd, [args, tbv] { return tbv->take(&args->engine) ? run_replay(*args) : kExitError; }};
}

}  // namespace voxvis::cli
