// export_cmd.cpp — `voxvis export`: a scene's voxels, and with --frames and
// --frame K the culling of frame K, written as OpenVDB grids (voxvis/vdb.h;
// docs/formats.md, "VDB export"). Frames 0..K are replayed as `voxvis
// replay` runs them (moves, then the frame, one viewer), so frame K's
// culling and its TBVs are the ones replay computes; only frame K is traced.
#include <cerrno>
#include <cinttypes>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <memory>
#include <string>

#include <unistd.h>

#include <CLI/CLI.hpp>

#include "cli.h"
#include "common.h"
#include "options.h"
#include "output_file.h"
#include "voxvis/format.h"
#include "voxvis/inspect.h"
#include "voxvis/scene.h"
#include "voxvis/vdb.h"

namespace voxvis::cli {
namespace {

/// Non-blank lines of the frames file (its frames), counted before the
/// scene is built so that a --frame beyond the file fails at once.
bool count_frames(const std::string& path, std::int64_t* count) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    report(FormatError{path, 0, "", std::string("cannot open: ") + std::strerror(errno)});
    return false;
  }
  *count = 0;
  std::string line;
  while (std::getline(in, line))
    if (!blank(line)) ++*count;
  if (in.bad()) {
    report(FormatError{path, 0, "", std::string("cannot read: ") + std::strerror(errno)});
    return false;
  }
  return true;
}

/// Replays frames 0..frame of `path` with one viewer; frame `frame` is
/// traced into `trace`, its input and result kept. On error reports it.
bool replay_to(const ExportArgs& args, Scene& scene, std::int64_t total, FrameTrace* trace, FrameInput* input,
               FrameResult* result) {
  std::ifstream frames(args.frames, std::ios::binary);
  if (!frames) {
    report(FormatError{args.frames, 0, "", std::string("cannot open: ") + std::strerror(errno)});
    return false;
  }
  const ViewerId viewer = scene.add_viewer();
  Scratch scratch;
  FormatError error;
  std::string line;
  int line_no = 0;
  std::int64_t index = 0;
  Progress progress(!args.quiet && ::isatty(STDERR_FILENO) != 0, static_cast<std::size_t>(args.frame + 1));
  while (index <= args.frame && std::getline(frames, line)) {
    ++line_no;
    if (blank(line)) continue;
    if (!parse_frame_line(line, args.frames, line_no, input, &error)) {
      progress.finish();
      report(error);
      return false;
    }
    if (!input->moves.empty()) {
      if (const Status st = scene.apply_moves(input->t, input->moves); !st.ok) {
        progress.finish();
        report(FormatError{args.frames, line_no, st.field, st.message});
        return false;
      }
    }
    if (index == args.frame) scratch.set_trace(trace);
    if (const Status st = scene.frame(viewer, input->camera, input->t, scratch, result); !st.ok) {
      progress.finish();
      report(FormatError{args.frames, line_no, st.field, st.message});
      return false;
    }
    ++index;
    progress.update(static_cast<std::size_t>(index));
  }
  progress.finish();
  if (frames.bad()) {
    report(FormatError{args.frames, line_no, "", std::string("cannot read: ") + std::strerror(errno)});
    return false;
  }
  if (index <= args.frame) {  // The file changed since it was counted.
    report(FormatError{args.frames, 0, "--frame",
                       "frame " + std::to_string(args.frame) + " is beyond the file's " + std::to_string(total) +
                           " frames"});
    return false;
  }
  return true;
}

}  // namespace

int run_export(const ExportArgs& args) {
  // The arguments CLI11 cannot check: --frame's range, --vdb a file.
  if (args.frame_given && args.frame < 0)
    return report(FormatError{"", 0, "--frame",
                              "must be a 0-based frame index >= 0, got " + std::to_string(args.frame)});
  if (args.vdb.empty() || args.vdb == "-")
    return report(FormatError{"", 0, "--vdb", "must name a file (a .vdb file cannot go to standard output)"});

  std::string text;
  SceneDesc desc;
  SceneOptions options;
  int code = kExitOk;
  if (!load_scene(args.engine, &text, &desc, &options, &code)) return code;
  // The frames and the output are checked before the (possibly slow) build.
  std::int64_t total = 0;
  if (!args.frames.empty()) {
    if (!count_frames(args.frames, &total)) return kExitError;
    if (total == 0) return report(FormatError{args.frames, 0, "", "no frames in the file (--frame needs one)"});
    if (args.frame >= total)
      return report(FormatError{args.frames, 0, "--frame",
                                "frame " + std::to_string(args.frame) + " is beyond the file's " +
                                    std::to_string(total) + " frames (0 to " + std::to_string(total - 1) + ")"});
  }
  OutputFile out;
  std::string message;
  if (!out.open(args.vdb, &message)) return report(FormatError{args.vdb, 0, "", message});

  std::unique_ptr<Scene> scene;
  if (!build_scene(args.engine, &text, desc, options, &scene, &code)) return code;
  if (const Status st = vdb::check_grid(scene->grid()); !st)
    return report(FormatError{args.engine.scene, 0, st.field, st.message});

  FrameTrace trace;
  FrameInput input;
  FrameResult result;
  vdb::FrameGrids frame;
  const bool with_frame = !args.frames.empty();
  if (with_frame) {
    if (!replay_to(args, *scene, total, &trace, &input, &result)) return kExitError;
    frame.index = static_cast<std::uint64_t>(args.frame);
    frame.t = result.t;
    frame.camera = input.camera;
    frame.occlusion_buffer = static_cast<int>(result.stats.ob_width);
    frame.trace = &trace;
    frame.pvs = &result.pvs;
  }
  vdb::ExportSummary sum;
  if (const Status st = vdb::write_vdb(out.temp_path(), *scene, args.engine.scene, with_frame ? &frame : nullptr, &sum,
                                       !out.direct());
      !st)
    return report(FormatError{args.vdb, 0, st.field, st.message});
  if (!out.commit(&message)) return report(FormatError{args.vdb, 0, "", message});

  if (!args.quiet) {
    const glm::ivec3 res = scene->grid().res;
    std::fprintf(stderr, "voxvis: wrote %s: grid %dx%dx%d; opaque %" PRIu64 " voxels, objects %" PRIu64 " voxels",
                 args.vdb.c_str(), res.x, res.y, res.z, sum.opaque, sum.objects);
    if (with_frame)
      std::fprintf(stderr,
                   "; frame %" PRId64 " (t %s): visited %" PRIu64 ", occluded %" PRIu64
                   " voxels, PVS %zu objects in %" PRIu64 " voxels",
                   args.frame, number_text(result.t).c_str(), sum.visited, sum.occluded, result.pvs.size(), sum.pvs);
    std::fputc('\n', stderr);
  }
  return kExitOk;
}

Command add_export_command(CLI::App& app) {
  auto args = std::make_shared<ExportArgs>();
  CLI::App* cmd = app.add_subcommand(
      "export", "Write the scene's voxels, and one frame's culling, as OpenVDB grids (for Houdini, Blender).");
  cmd->add_option("--scene", args->engine.scene, "Scene file (JSON, format voxvis-scene/1)")
      ->required()
      ->type_name("FILE");
  CLI::Option* frames = cmd->add_option("--frames", args->frames, "Frames file (JSON Lines), as for replay")
                            ->type_name("FILE");
  CLI::Option* frame =
      cmd->add_option("--frame", args->frame,
                      "0-based frame of --frames whose culling to write (frames 0..K are replayed)")
          ->type_name("K");
  frame->needs(frames);
  frames->needs(frame);
  cmd->add_option("--vdb", args->vdb, "OpenVDB file to write, whole or not at all")
      ->required()
      ->type_name("FILE");
  cmd->add_option("--grid", args->engine.grid, "Grid resolution overriding the scene's, as for replay")
      ->type_name("NX,NY,NZ");
  const auto tbv = add_tbv_period_option(cmd, "TBV period for the engine, as for replay");
  cmd->add_option("--occlusion-buffer", args->engine.occlusion_buffer,
                  "Occlusion buffer width, as for replay (0: off, the voxel traversal; default 160)")
      ->type_name("PIXELS");
  cmd->add_flag("-q,--quiet", args->quiet, "No progress line and no summary on stderr");
  cmd->footer(
      "Grids: opaque (bool: static opacity) and objects (int32: objects touching each voxel,\n"
      "dynamic ones where frame K's moves left them); with --frame, visited and occluded\n"
      "(bool: what frame K's traversal did) and pvs (bool: voxels of frame K's PVS objects).\n"
      "Index (i,j,k) is voxel (i,j,k); the transform puts its centre at\n"
      "bounds.min + (i+0.5, j+0.5, k+0.5) * voxel_size (docs/formats.md, \"VDB export\").");
  return {cmd, [args, tbv, frame] {
            if (!tbv->take(&args->engine)) return kExitError;
            args->frame_given = frame->count() > 0;
            return run_export(*args);
          }};
}

}  // namespace voxvis::cli
