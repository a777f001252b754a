// verify_cmd.cpp — `voxvis verify`: renders every frame headlessly (render/),
// or casts it with the CPU ray caster (raycast/) where no EGL is available,
// takes the objects that show at pixel level, and reports each one missing
// from the frame's PVS (the engine's, or a PVS file's). What EGL shows but
// the PVS lacks is a miss only when the double-precision caster confirms it
// near a pixel centre (docs/verify.md, "What a miss is").
#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <deque>
#include <fstream>
#include <memory>
#include <string>
#include <unordered_map>
#include <vector>

#include <unistd.h>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "cli.h"
#include "common.h"
#include "options.h"
#include "output_file.h"
#include "reference.h"
#include "voxvis/format.h"
#include "voxvis/raycast.h"
#include "voxvis/render.h"
#include "voxvis/scene.h"

namespace voxvis::cli {
namespace {

/// The PVS lines of a recording, read one per frame as the frames are.
class PvsReader {
 public:
  bool open(const std::string& path, std::string* message) {
    path_ = path;
    in_.open(path, std::ios::binary);
    if (!in_) {
      *message = path + ": cannot open: " + std::strerror(errno);
      return false;
    }
    return true;
  }
  /// The PVS of frame `index` (ascending ids), checked against the scene's ids.
  bool next(std::size_t index, const std::unordered_map<ObjectId, std::size_t>& known, std::vector<ObjectId>* pvs,
            std::string* message) {
    std::string line;
    while (std::getline(in_, line)) {
      ++line_no_;
      if (blank(line)) continue;
      const std::string where = path_ + ":" + std::to_string(line_no_);
      const nlohmann::json j = nlohmann::json::parse(line, nullptr, false);
      if (j.is_discarded() || !j.is_object()) {
        *message = where + ": not a JSON object";
        return false;
      }
      if (!j.contains("frame") || !j["frame"].is_number_unsigned() || j["frame"].get<std::uint64_t>() != index) {
        *message = where + ": frame: expected " + std::to_string(index) +
                   " (one line per frame of the frames file, in order)";
        return false;
      }
      if (!j.contains("pvs") || !j["pvs"].is_array()) {
        *message = where + ": pvs: missing or not an array";
        return false;
      }
      pvs->clear();
      for (const auto& v : j["pvs"]) {
        if (!v.is_number_unsigned() || v.get<std::uint64_t>() > 0xffffffffu) {
          *message = where + ": pvs: " + v.dump() + " is not an object id";
          return false;
        }
        const auto id = static_cast<ObjectId>(v.get<std::uint64_t>());
        if (!known.count(id)) {
          *message = where + ": pvs: id " + std::to_string(id) + " is not an object of the scene";
          return false;
        }
        pvs->push_back(id);
      }
      std::sort(pvs->begin(), pvs->end());
      pvs->erase(std::unique(pvs->begin(), pvs->end()), pvs->end());
      return true;
    }
    if (in_.bad()) {
      *message = path_ + ": cannot read: " + std::strerror(errno);
      return false;
    }
    *message = path_ + ": has no line for frame " + std::to_string(index) + " (" + std::to_string(index) +
               " PVS lines for more frames)";
    return false;
  }
  /// Whether only blank lines remain.
  bool at_end() {
    std::string line;
    while (std::getline(in_, line)) {
      ++line_no_;
      if (!blank(line)) return false;
    }
    return true;
  }
  int line() const { return line_no_; }

 private:
  std::string path_;
  std::ifstream in_;
  int line_no_ = 0;
};

std::string json_ids(const std::vector<ObjectId>& ids) {
  std::string s = "[";
  for (std::size_t i = 0; i < ids.size(); ++i) {
    if (i) s += ',';
    s += std::to_string(ids[i]);
  }
  return s + "]";
}

/// Milliseconds to the microsecond, as JSON (timings are never NaN).
std::string ms(double v) { return number_text(std::round(v * 1000.0) / 1000.0); }

/// A frame checked, its line not yet written: a region frame waits for the
/// frames of its horizon (--horizon-frames), and every frame after it waits
/// with it, so that lines stay in order.
struct Checked {
  std::int64_t index = 0;
  int line_no = 0;
  Camera camera;
  double t = 0.0;
  std::vector<ObjectId> pvs, vis, missed, edge_only;
  render::VisibleStats rs;
  bool waits = false;  ///< Still takes later frames' objects.
};

/// Adds to a region frame's check the objects as a later frame placed them
/// (`objects`): the sampled region at those positions (no further
/// placement), its sightings and misses merged in.
void check_later(Checked* c, const std::vector<ObjectDesc>& objects, std::int64_t later, int w, int h, int eyes) {
  Camera cam = c->camera;
  cam.horizon_s = 0.0;  // The objects are where they went.
  raycast::RegionSampling sampling;
  sampling.random_eyes = eyes;
  sampling.rays = raycast::pixel_centres(w, h);
  sampling.seed = static_cast<std::uint64_t>(c->index) * 7919 + static_cast<std::uint64_t>(later) + 1;
  const std::vector<ObjectId> seen = raycast::region_visible(objects, cam, sampling);
  std::vector<ObjectId> merged;
  std::set_union(c->vis.begin(), c->vis.end(), seen.begin(), seen.end(), std::back_inserter(merged));
  c->vis.swap(merged);
  c->missed.clear();
  std::set_difference(c->vis.begin(), c->vis.end(), c->pvs.begin(), c->pvs.end(), std::back_inserter(c->missed));
}

/// The flags, checked: the pixels, how EGL finds the visible set, who is
/// the reference, and the region set on every frame.
struct VerifyFlags {
  int w = 0, h = 0;
  render::Method method = render::Method::Ids;
  Reference reference = Reference::Auto;
  render::ContextOptions ctx;
  RegionOverride region;
};

/// Checks the flags in this order; false, with `error` naming the first bad one.
bool check_verify_flags(const VerifyArgs& args, VerifyFlags* f, FormatError* error) {
  const auto bad = [error](const char* flag, const std::string& message) {
    *error = FormatError{"", 0, flag, message};
    return false;
  };
  std::string message;
  if (!render::parse_resolution(args.resolution, &f->w, &f->h, &message)) return bad("--resolution", message);
  if (!render::parse_method(args.method, &f->method, &message)) return bad("--method", message);
  if (!parse_reference_flags(args.reference, args.egl, &f->reference, &f->ctx, error)) return false;
  if (f->reference == Reference::Raycast && f->method == render::Method::Queries)
    return bad("--method", "queries needs the EGL reference (not --reference raycast)");
  if (args.first_frame < 0) return bad("--first-frame", "must be >= 0");
  if (!parse_region_args(args.region, &f->region, error)) return false;
  if (args.region_eyes < 0 || args.region_eyes > 1000)
    return bad("--region-eyes", "must be in [0, 1000], got " + std::to_string(args.region_eyes));
  if (args.frame_count < -1) return bad("--frame-count", "must be >= 0");
  if (args.horizon_frames < 0 || args.horizon_frames > 1000)
    return bad("--horizon-frames", "must be in [0, 1000], got " + std::to_string(args.horizon_frames));
  return true;
}

/// The frames to verify, for the progress bar: one pass over the file,
/// which is then rewound.
std::size_t frames_in_slice(std::ifstream& frames, const VerifyArgs& args) {
  std::string l;
  std::int64_t n = 0;
  while (std::getline(frames, l))
    if (!blank(l)) ++n;
  const std::int64_t last = args.frame_count < 0 ? n : std::min(n, args.first_frame + args.frame_count);
  frames.clear();
  frames.seekg(0);
  return last > args.first_frame ? static_cast<std::size_t>(last - args.first_frame) : 0;
}

/// The reference before the engine: EGL's renderer, else (--reference auto)
/// the CPU ray caster through the same pixel centres (`*renderer` stays
/// null, `egl_error` says why). With --reference egl, a machine without EGL
/// fails at once. On error reports it and returns false.
bool open_verify_reference(const VerifyArgs& args, const VerifyFlags& f, std::unique_ptr<render::Renderer>* renderer,
                           std::string* egl_error) {
  if (f.reference != Reference::Raycast) *renderer = render::Renderer::create(f.ctx, egl_error);
  if (!*renderer && f.reference == Reference::Egl) {
    report_message("EGL: " + *egl_error);
    return false;
  }
  if (!*renderer && f.method == render::Method::Queries) {
    report(FormatError{"", 0, "--method", "queries needs the EGL reference (EGL: " + *egl_error + ")"});
    return false;
  }
  if (*renderer && (f.w > (*renderer)->info().max_size || f.h > (*renderer)->info().max_size)) {
    report(FormatError{"", 0, "--resolution",
                       args.resolution + " exceeds this OpenGL's limit of " +
                           std::to_string((*renderer)->info().max_size) + " pixels a side"});
    return false;
  }
  return true;
}

/// Whether every visible object is looked for (the ray caster, the id
/// buffer, --full), not only those of the PVS (occlusion queries).
bool checks_every_object(const VerifyArgs& args, const VerifyFlags& f, bool by_egl) {
  return !by_egl || f.method == render::Method::Ids || args.full;
}

/// Where a frame's PVS comes from: the engine, which runs every frame (its
/// state depends on the frames before), or the --pvs file, read line by
/// line.
struct PvsSource {
  std::unique_ptr<Scene> scene;  ///< Null with --pvs.
  ViewerId viewer = 0;
  PvsReader file;
};

/// What the written lines add up to, for the summary.
struct VerifyTotals {
  std::uint64_t visible = 0, pvs = 0, missed = 0, frames_missed = 0, edge_only = 0, verified = 0;
  std::vector<double> draw_ms, read_ms, query_ms;
};

/// One verification: the frames read one by one, each frame of the slice
/// checked against the reference, the lines written in frame order.
class VerifyRun {
 public:
  VerifyRun(const VerifyArgs& args, const VerifyFlags& flags, render::Renderer* renderer, PvsSource* source,
            OutputFile* out, std::vector<ObjectDesc> objects, bool tty, std::size_t slice)
      : args_(args), f_(flags), renderer_(renderer), source_(source), out_(out), objects_(std::move(objects)),
        progress_(tty, slice) {
    for (std::size_t i = 0; i < objects_.size(); ++i) slot_[objects_[i].id] = i;
  }

  /// Reads the frames up to the slice's end (or the file's) and writes
  /// their lines; kExitOk, or an error's status (reported).
  int check_frames(std::ifstream& frames) {
    std::string line;
    while (index_ < end() && std::getline(frames, line)) {
      ++line_no_;
      if (blank(line)) continue;
      FormatError error;
      if (!parse_frame_line(line, args_.frames, line_no_, &frame_, &error)) return fail(report(error));
      f_.region.apply(&frame_.camera);
      if (!place_objects(&error)) return fail(report(error));
      if (const int code = next_pvs(); code != kExitOk) return fail(code);
      if (index_ < args_.first_frame) {
        ++index_;
        continue;
      }
      recheck_waiting();
      Checked c;
      std::string message;
      if (!check(&c, &message)) return fail(report(FormatError{args_.frames, line_no_, "", message}));
      window_.push_back(std::move(c));
      if (!flush(false)) return write_error();
      ++index_;
    }
    if (!flush(true)) return write_error();
    if (frames.bad())
      return fail(report(FormatError{args_.frames, line_no_, "", std::string("cannot read: ") + std::strerror(errno)}));
    progress_.finish();
    return kExitOk;
  }

  /// Frames read (the file's count when it ended before the slice did).
  std::int64_t frames_read() const { return index_; }
  /// The last frame to verify, plus one.
  std::int64_t end() const {
    return args_.frame_count < 0 ? INT64_MAX : args_.first_frame + args_.frame_count;
  }
  const VerifyTotals& totals() const { return totals_; }

 private:
  int fail(int status) {
    progress_.finish();
    return status;
  }
  int write_error() {
    return fail(report(FormatError{out_->path(), 0, "", std::string("cannot write: ") + std::strerror(errno)}));
  }

  /// Places the frame's moved objects. Checked here too: with --pvs no
  /// engine sees the moves.
  bool place_objects(FormatError* error) {
    for (std::size_t i = 0; i < frame_.moves.size(); ++i) {
      const Move& mv = frame_.moves[i];
      const std::string field = "moves[" + std::to_string(i) + "].id";
      const auto it = slot_.find(mv.id);
      if (it == slot_.end()) {
        *error = FormatError{args_.frames, line_no_, field, "unknown object id " + std::to_string(mv.id)};
        return false;
      }
      if (!objects_[it->second].dynamic) {
        *error = FormatError{args_.frames, line_no_, field,
                             "object " + std::to_string(mv.id) + " is static and cannot move"};
        return false;
      }
      ObjectDesc& o = objects_[it->second];
      o.center = mv.center;
      if (mv.has_rotation && o.shape == Shape::Mesh) o.rotation = mv.rotation;
    }
    return true;
  }

  /// The frame's PVS into `pvs_`, from the engine or the PVS file; both
  /// run on every frame, the ones before the slice too. kExitOk, or an
  /// error's status (reported).
  int next_pvs() {
    if (Scene* scene = source_->scene.get()) {
      if (!frame_.moves.empty()) {
        MoveReport moves;
        if (const Status st = scene->apply_moves(frame_.t, frame_.moves, &moves); !st.ok)
          return report(FormatError{args_.frames, line_no_, st.field, st.message});
      }
      if (const Status st = scene->frame(source_->viewer, frame_.camera, frame_.t, scratch_, &result_); !st.ok)
        return report(FormatError{args_.frames, line_no_, st.field, st.message});
      pvs_ = result_.pvs;
      return kExitOk;
    }
    std::string message;
    if (!source_->file.next(static_cast<std::size_t>(index_), slot_, &pvs_, &message)) return report_message(message);
    return kExitOk;
  }

  /// Earlier region frames whose horizon holds this frame: checked with
  /// the objects where this frame put them.
  void recheck_waiting() {
    for (Checked& c : window_) {
      if (!c.waits) continue;
      if (frame_.t - c.t > c.camera.horizon_s) {
        c.waits = false;
        continue;
      }
      check_later(&c, objects_, index_, f_.w, f_.h, args_.region_eyes);
      c.waits = index_ - c.index < args_.horizon_frames;
    }
  }

  /// Checks this frame's PVS against the reference; false, with `message`,
  /// when the reference fails.
  bool check(Checked* c, std::string* message) {
    c->index = index_;
    c->line_no = line_no_;
    c->camera = frame_.camera;
    c->t = frame_.t;
    c->pvs = pvs_;
    if (is_region(frame_.camera)) {
      check_region(c);
      return true;
    }
    const bool checks_all = checks_every_object(args_, f_, renderer_ != nullptr);
    const bool ok = renderer_ != nullptr
                        ? renderer_->visible(objects_, frame_.camera, render::VisibleOptions{f_.w, f_.h, f_.method},
                                             checks_all ? nullptr : &c->pvs, &c->vis, &c->rs, message)
                        : raycast_visible(objects_, frame_.camera, f_.w, f_.h, &c->vis, &c->rs, message);
    if (!ok) return false;
    // A miss as report counts one (reference.h): EGL's sightings confirmed
    // in double precision, the edge-only ones dismissed.
    return confirm_misses(renderer_, objects_, frame_.camera, f_.w, f_.h, f_.method == render::Method::Ids, c->vis,
                          c->pvs, &c->missed, &c->edge_only, message);
  }

  /// A region: the ray caster's sampling of it (raycast::region_visible),
  /// every sighting a double-precision first hit.
  void check_region(Checked* c) {
    if (!region_noted_ && !args_.quiet) {
      progress_.finish();
      const std::string later = args_.horizon_frames > 0 ? ", and with the objects of the next " +
                                                               std::to_string(args_.horizon_frames) +
                                                               " frames within its horizon"
                                                         : "";
      std::fprintf(stderr, "voxvis: region frames are checked by the CPU ray caster's sampling: %dx%d rays "
                           "a view from the eye box's centre, 8 corners and %d random eyes%s%s\n",
                   f_.w, f_.h, args_.region_eyes, frame_.camera.omnidirectional ? ", six faces each" : "",
                   later.c_str());
      region_noted_ = true;
    }
    raycast::RegionSampling sampling;
    sampling.random_eyes = args_.region_eyes;
    sampling.rays = raycast::pixel_centres(f_.w, f_.h);
    sampling.seed = static_cast<std::uint64_t>(index_) + 1;
    c->vis = raycast::region_visible(objects_, frame_.camera, sampling);
    std::set_difference(c->vis.begin(), c->vis.end(), c->pvs.begin(), c->pvs.end(), std::back_inserter(c->missed));
    c->waits = args_.horizon_frames > 0 && frame_.camera.horizon_s > 0.0;
  }

  /// Writes the frames at the window's front that wait no more (all: every one).
  bool flush(bool all) {
    while (!window_.empty() && (all || !window_.front().waits)) {
      if (!write(window_.front())) return false;
      window_.pop_front();
    }
    return true;
  }

  /// A checked frame's line, its miss message and its part of the totals.
  bool write(const Checked& c) {
    const render::VisibleStats& rs = c.rs;
    out_line_ = "{\"frame\":" + std::to_string(c.index) + ",\"visible\":" + json_ids(c.vis) +
                ",\"missed\":" + json_ids(c.missed) + ",\"edge_only\":" + json_ids(c.edge_only) +
                ",\"pvs_size\":" + std::to_string(c.pvs.size()) +
                ",\"stats\":{\"in_frustum\":" + std::to_string(rs.in_frustum) +
                ",\"queries\":" + std::to_string(rs.queries) + ",\"upload_ms\":" + ms(rs.upload_ms) +
                ",\"draw_ms\":" + ms(rs.draw_ms) + ",\"query_ms\":" + ms(rs.query_ms) +
                ",\"read_ms\":" + ms(rs.read_ms) + "}}\n";
    if (!out_->write(out_line_)) return false;
    if (!c.missed.empty() && !args_.quiet) {
      progress_.finish();
      std::fprintf(stderr, "voxvis: MISS: frame %lld (%s:%d): %zu visible object(s) not in the PVS: %s\n",
                   static_cast<long long>(c.index), args_.frames.c_str(), c.line_no, c.missed.size(),
                   json_ids(c.missed).c_str());
    }
    totals_.visible += c.vis.size();
    totals_.pvs += c.pvs.size();
    totals_.missed += c.missed.size();
    totals_.edge_only += c.edge_only.size();
    totals_.frames_missed += c.missed.empty() ? 0 : 1;
    totals_.draw_ms.push_back(rs.draw_ms);
    totals_.read_ms.push_back(rs.read_ms);
    totals_.query_ms.push_back(rs.query_ms);
    ++totals_.verified;
    progress_.update(static_cast<std::size_t>(totals_.verified));
    return true;
  }

  const VerifyArgs& args_;
  VerifyFlags f_;
  render::Renderer* renderer_;  ///< Null: the CPU ray caster is the reference.
  PvsSource* source_;
  OutputFile* out_;
  std::vector<ObjectDesc> objects_;                  ///< Where the frames so far put them.
  std::unordered_map<ObjectId, std::size_t> slot_;  ///< id -> index in objects_.
  Progress progress_;
  std::int64_t index_ = 0;  ///< The frame being read (0-based, blank lines not counted).
  int line_no_ = 0;
  FrameInput frame_;
  Scratch scratch_;
  FrameResult result_;
  std::vector<ObjectId> pvs_;
  std::string out_line_;
  bool region_noted_ = false;
  std::deque<Checked> window_;  ///< Frames checked, lines not yet written (--horizon-frames).
  VerifyTotals totals_;
};

/// After the frames: the slice and the PVS file must have matched the
/// frames file. On a mismatch reports it and returns false.
bool check_verify_coverage(const VerifyArgs& args, const VerifyRun& run, PvsReader* pvs_file) {
  const std::int64_t first = args.first_frame, end = run.end(), index = run.frames_read();
  if (args.frame_count > 0 && index < end) {
    report(FormatError{args.frames, 0, "--frame-count",
                       "asked for frames " + std::to_string(first) + " to " + std::to_string(end - 1) +
                           ", the file has " + std::to_string(index)});
    return false;
  }
  if (index < first) {
    report(FormatError{args.frames, 0, "--first-frame",
                       "is " + std::to_string(first) + ", the file has " + std::to_string(index) + " frames"});
    return false;
  }
  if (!args.pvs.empty() && args.frame_count < 0 && !pvs_file->at_end()) {
    report_message(args.pvs + ":" + std::to_string(pvs_file->line()) + ": more PVS lines than frames (" +
                   std::to_string(index) + " frames in " + args.frames + ")");
    return false;
  }
  return true;
}

/// The summary line on stderr.
void print_verify_summary(const VerifyTotals& t, int w, int h, const char* by) {
  const Spread d = spread(t.draw_ms), r = spread(t.read_ms), q = spread(t.query_ms);
  const std::string dismissed =
      t.edge_only == 0 ? ""
                       : "; " + std::to_string(t.edge_only) +
                             " edge-only sightings dismissed (EGL's single precision; not visible by the "
                             "definition)";
  std::fprintf(stderr,
               "voxvis: verified %llu frames at %dx%d (%s): %llu missed object-frames in %llu frames%s; "
               "visible %llu, PVS %llu, tightness %.3f; draw ms median %.2f p99 %.2f, queries %.2f, "
               "read %.2f\n",
               static_cast<unsigned long long>(t.verified), w, h, by, static_cast<unsigned long long>(t.missed),
               static_cast<unsigned long long>(t.frames_missed), dismissed.c_str(),
               static_cast<unsigned long long>(t.visible), static_cast<unsigned long long>(t.pvs),
               t.visible ? static_cast<double>(t.pvs) / static_cast<double>(t.visible) : 0.0, d.median, d.p99,
               q.median, r.median);
}

}  // namespace

int run_verify(const VerifyArgs& args) {
  VerifyFlags flags;
  FormatError flag_error;
  if (!check_verify_flags(args, &flags, &flag_error)) return report(flag_error);
  std::string text;
  SceneDesc desc;
  SceneOptions options;
  int code = kExitOk;
  if (!load_scene(args.engine, &text, &desc, &options, &code)) return code;

  std::ifstream frames(args.frames, std::ios::binary);
  if (!frames) return report(FormatError{args.frames, 0, "", std::string("cannot open: ") + std::strerror(errno)});
  const bool tty = !args.quiet && ::isatty(STDERR_FILENO) != 0;
  const std::size_t slice = tty ? frames_in_slice(frames, args) : 0;
  std::string message;
  PvsSource source;
  if (!args.pvs.empty() && !source.file.open(args.pvs, &message)) return report_message(message);
  OutputFile out;
  if (!out.open(args.out, &message)) return report(FormatError{args.out, 0, "", message});
  std::unique_ptr<render::Renderer> renderer;
  std::string egl_error;
  if (!open_verify_reference(args, flags, &renderer, &egl_error)) return kExitError;
  if (args.pvs.empty()) {
    if (!build_scene(args.engine, &text, desc, options, &source.scene, &code)) return code;
    source.viewer = source.scene->add_viewer();
  }

  const bool by_egl = renderer != nullptr;
  const bool checks_all = checks_every_object(args, flags, by_egl);
  const char* by = by_egl ? render::method_name(flags.method) : "raycast";
  if (!args.quiet) {
    if (!by_egl && flags.reference == Reference::Auto)
      std::fprintf(stderr, "voxvis: EGL: %s; verifying with the CPU ray caster\n", egl_error.c_str());
    std::fprintf(stderr, "voxvis: verifying at %dx%d by %s on %s%s\n", flags.w, flags.h, by,
                 by_egl ? renderer->info().summary().c_str() : raycast_summary().c_str(),
                 checks_all ? "" : "; only the PVS is probed, misses are not checked (add --full)");
  }
  VerifyRun run(args, flags, renderer.get(), &source, &out, desc.objects, tty, slice);
  if (const int status = run.check_frames(frames); status != kExitOk) return status;
  if (!check_verify_coverage(args, run, &source.file)) return kExitError;
  if (!out.commit(&message)) return report(FormatError{out.path(), 0, "", message});
  if (!args.quiet) print_verify_summary(run.totals(), flags.w, flags.h, by);
  return run.totals().missed > 0 ? kExitMissed : kExitOk;
}

Command add_verify_command(CLI::App& app) {
  auto args = std::make_shared<VerifyArgs>();
  CLI::App* cmd = app.add_subcommand(
      "verify",
      "Render every frame headlessly (EGL, else the CPU ray caster) and report the visible objects missing "
      "from its PVS.");
  cmd->add_option("--scene", args->engine.scene, "Scene file (JSON, format voxvis-scene/1)")
      ->required()
      ->type_name("FILE");
  cmd->add_option("--frames", args->frames, "Frames file (JSON Lines), as for replay")
      ->required()
      ->type_name("FILE");
  cmd->add_option("--pvs", args->pvs, "PVS lines to check (replay's or view's output); default: run the engine")
      ->type_name("FILE");
  cmd->add_option("--out", args->out, "Output file (JSON Lines); default stdout")->type_name("FILE");
  cmd->add_option("--resolution", args->resolution, "Pixels of the rendered frames")
      ->type_name("WxH")
      ->capture_default_str();
  cmd->add_option("--reference", args->reference,
                  "Who finds the visible set at the pixel centres: egl (the headless renderer), raycast "
                  "(the CPU ray caster), auto (EGL when a context starts, else the ray caster)")
      ->type_name("auto|egl|raycast")
      ->capture_default_str();
  cmd->add_option("--method", args->method,
                  "With EGL, ids: one id buffer read back; queries: one occlusion query per object")
      ->type_name("ids|queries")
      ->capture_default_str();
  cmd->add_flag("--full", args->full,
                "With --method queries, probe every object in the frustum, so that misses are "
                "caught (the id buffer always sees them all)");
  cmd->add_option("--first-frame", args->first_frame, "First frame to verify (0-based)")
      ->type_name("N")
      ->capture_default_str();
  cmd->add_option("--frame-count", args->frame_count, "Frames to verify; -1: to the end")
      ->type_name("N")
      ->capture_default_str();
  add_egl_options(cmd, &args->egl);
  cmd->add_option("--grid", args->engine.grid, "Grid resolution for the engine, as for replay")
      ->type_name("NX,NY,NZ");
  const auto tbv = add_tbv_period_option(cmd, "TBV period for the engine, as for replay");
  cmd->add_option("--occlusion-buffer", args->engine.occlusion_buffer,
                  "Occlusion buffer width for the engine, as for replay (0: off; default 160)")
      ->type_name("PIXELS");
  add_region_options(cmd, &args->region);
  cmd->add_option("--region-eyes", args->region_eyes,
                  "Region frames: eyes sampled at random in the eye box besides its centre and 8 "
                  "corners (0..1000)")
      ->type_name("N")
      ->capture_default_str();
  cmd->add_option("--horizon-frames", args->horizon_frames,
                  "Region frames: frame j's PVS also checked against the objects where frames "
                  "j+1..j+K put them, while within its horizon_s (0..1000)")
      ->type_name("K")
      ->capture_default_str();
  cmd->add_flag("-q,--quiet", args->quiet, "No progress, miss lines or summary on stderr");
  cmd->footer(
      "Output: one line per frame, {\"frame\", \"visible\", \"missed\", \"pvs_size\", \"stats\"}.\n"
      "Exit status 3 when any visible object was missing from a PVS (docs/verify.md).");
  return {cmd, [args, tbv] { return tbv->take(&args->engine) ? run_verify(*args) : kExitError; }};
}

}  // namespace voxvis::cli
