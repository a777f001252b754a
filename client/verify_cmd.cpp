// verify_cmd.cpp — `voxvis verify`: renders every frame headlessly (render/),
// or casts it with the CPU ray caster (raycast/) where no EGL is available,
// takes the objects that show at pixel level, and reports each one missing
// from the frame's PVS (the engine's, or a PVS file's). What EGL shows but
// the PVS lacks is a miss only when the double-precision caster confirms it
// near a pixel centre (docs/verify.md, "What a miss is").
#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <deque>
#include <fstream>
#include <memory>
#include <string>
#include <unordered_map>
#include <vector>

#include <unistd.h>

#include <nlohmann/json.hpp>

#include "cli.h"
#include "common.h"
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

std::string ms(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3f", v);
  return buf;
}

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

}  // namespace

int run_verify(const VerifyArgs& args) {
  int w = 0, h = 0;
  std::string message;
  if (!render::parse_resolution(args.resolution, &w, &h, &message)) return report(FormatError{"", 0, "--resolution", message});
  render::Method method;
  if (!render::parse_method(args.method, &method, &message)) return report(FormatError{"", 0, "--method", message});
  Reference reference_kind = Reference::Auto;
  render::ContextOptions ctx;
  FormatError flag_error;
  if (!parse_reference_flags(args.reference, args.egl, &reference_kind, &ctx, &flag_error)) return report(flag_error);
  if (reference_kind == Reference::Raycast && method == render::Method::Queries)
    return report(FormatError{"", 0, "--method", "queries needs the EGL reference (not --reference raycast)"});
  if (args.first_frame < 0) return report(FormatError{"", 0, "--first-frame", "must be >= 0"});
  RegionOverride region;
  if (!parse_region_args(args.region, &region, &flag_error)) return report(flag_error);
  if (args.region_eyes < 0 || args.region_eyes > 1000)
    return report(FormatError{"", 0, "--region-eyes", "must be in [0, 1000], got " + std::to_string(args.region_eyes)});
  if (args.frame_count < -1) return report(FormatError{"", 0, "--frame-count", "must be >= 0"});
  if (args.horizon_frames < 0 || args.horizon_frames > 1000)
    return report(FormatError{"", 0, "--horizon-frames",
                              "must be in [0, 1000], got " + std::to_string(args.horizon_frames)});

  std::string text;
  SceneDesc desc;
  SceneOptions options;
  int code = kExitOk;
  if (!load_scene(args.engine, &text, &desc, &options, &code)) return code;
  std::unordered_map<ObjectId, std::size_t> slot;  // id -> index in objects
  std::vector<ObjectDesc> objects = desc.objects;
  for (std::size_t i = 0; i < objects.size(); ++i) slot[objects[i].id] = i;

  std::ifstream frames(args.frames, std::ios::binary);
  if (!frames) return report(FormatError{args.frames, 0, "", std::string("cannot open: ") + std::strerror(errno)});
  // The frames to verify, for the progress bar: one pass over the file.
  std::size_t slice = 0;
  const bool tty = !args.quiet && ::isatty(STDERR_FILENO) != 0;
  if (tty) {
    std::string l;
    std::int64_t n = 0;
    while (std::getline(frames, l))
      if (!blank(l)) ++n;
    const std::int64_t last = args.frame_count < 0 ? n : std::min(n, args.first_frame + args.frame_count);
    slice = last > args.first_frame ? static_cast<std::size_t>(last - args.first_frame) : 0;
    frames.clear();
    frames.seekg(0);
  }
  PvsReader pvs_in;
  if (!args.pvs.empty() && !pvs_in.open(args.pvs, &message)) return report_message(message);
  OutputFile out;
  if (!out.open(args.out, &message)) return report(FormatError{args.out, 0, "", message});

  // The reference before the engine: EGL's renderer, else (--reference auto)
  // the CPU ray caster through the same pixel centres. With --reference egl,
  // a machine without EGL fails at once.
  std::unique_ptr<render::Renderer> renderer;
  std::string egl_error;
  if (reference_kind != Reference::Raycast) renderer = render::Renderer::create(ctx, &egl_error);
  if (!renderer && reference_kind == Reference::Egl) return report_message("EGL: " + egl_error);
  const bool by_egl = renderer != nullptr;
  if (!by_egl && method == render::Method::Queries)
    return report(FormatError{"", 0, "--method", "queries needs the EGL reference (EGL: " + egl_error + ")"});
  if (by_egl && (w > renderer->info().max_size || h > renderer->info().max_size))
    return report(FormatError{"", 0, "--resolution",
                              args.resolution + " exceeds this OpenGL's limit of " +
                                  std::to_string(renderer->info().max_size) + " pixels a side"});

  std::unique_ptr<Scene> scene;
  ViewerId viewer = 0;
  if (args.pvs.empty()) {
    if (!build_scene(args.engine, &text, desc, options, &scene, &code)) return code;
    viewer = scene->add_viewer();
  }
  const bool checks_all = !by_egl || method == render::Method::Ids || args.full;
  const char* by = by_egl ? render::method_name(method) : "raycast";
  if (!args.quiet) {
    if (!by_egl && reference_kind == Reference::Auto)
      std::fprintf(stderr, "voxvis: EGL: %s; verifying with the CPU ray caster\n", egl_error.c_str());
    std::fprintf(stderr, "voxvis: verifying at %dx%d by %s on %s%s\n", w, h, by,
                 by_egl ? renderer->info().summary().c_str() : raycast_summary().c_str(),
                 checks_all ? "" : "; only the PVS is probed, misses are not checked (add --full)");
  }

  const std::int64_t first = args.first_frame;
  const std::int64_t end = args.frame_count < 0 ? INT64_MAX : first + args.frame_count;
  Scratch scratch;
  FrameInput frame;
  FrameResult result;
  FormatError error;
  std::vector<ObjectId> pvs;
  std::vector<double> draw_ms, read_ms, query_ms;
  std::uint64_t total_visible = 0, total_pvs = 0, total_missed = 0, frames_missed = 0, total_edge_only = 0,
                verified = 0;
  std::int64_t index = 0;
  int line_no = 0;
  std::string line, out_line;
  Progress progress(tty, slice);
  bool region_noted = false;
  std::deque<Checked> window;  // Frames checked, lines not yet written (--horizon-frames).

  auto fail = [&](int status) {
    progress.finish();
    return status;
  };
  // A checked frame's line, its miss message and its part of the totals.
  auto write = [&](const Checked& c) -> bool {
    const render::VisibleStats& rs = c.rs;
    out_line = "{\"frame\":" + std::to_string(c.index) + ",\"visible\":" + json_ids(c.vis) +
               ",\"missed\":" + json_ids(c.missed) + ",\"edge_only\":" + json_ids(c.edge_only) +
               ",\"pvs_size\":" + std::to_string(c.pvs.size()) +
               ",\"stats\":{\"in_frustum\":" + std::to_string(rs.in_frustum) +
               ",\"queries\":" + std::to_string(rs.queries) + ",\"upload_ms\":" + ms(rs.upload_ms) +
               ",\"draw_ms\":" + ms(rs.draw_ms) + ",\"query_ms\":" + ms(rs.query_ms) +
               ",\"read_ms\":" + ms(rs.read_ms) + "}}\n";
    if (!out.write(out_line)) return false;
    if (!c.missed.empty() && !args.quiet) {
      progress.finish();
      std::fprintf(stderr, "voxvis: MISS: frame %lld (%s:%d): %zu visible object(s) not in the PVS: %s\n",
                   static_cast<long long>(c.index), args.frames.c_str(), c.line_no, c.missed.size(),
                   json_ids(c.missed).c_str());
    }
    total_visible += c.vis.size();
    total_pvs += c.pvs.size();
    total_missed += c.missed.size();
    total_edge_only += c.edge_only.size();
    frames_missed += c.missed.empty() ? 0 : 1;
    draw_ms.push_back(rs.draw_ms);
    read_ms.push_back(rs.read_ms);
    query_ms.push_back(rs.query_ms);
    ++verified;
    progress.update(static_cast<std::size_t>(verified));
    return true;
  };
  // Writes the frames at the window's front that wait no more (all: every one).
  auto flush = [&](bool all) -> bool {
    while (!window.empty() && (all || !window.front().waits)) {
      if (!write(window.front())) return false;
      window.pop_front();
    }
    return true;
  };
  auto write_error = [&]() {
    return fail(report(FormatError{out.path(), 0, "", std::string("cannot write: ") + std::strerror(errno)}));
  };
  while (index < end && std::getline(frames, line)) {
    ++line_no;
    if (blank(line)) continue;
    if (!parse_frame_line(line, args.frames, line_no, &frame, &error)) return fail(report(error));
    region.apply(&frame.camera);
    for (std::size_t i = 0; i < frame.moves.size(); ++i) {
      // Checked here too: with --pvs no engine sees the moves.
      const Move& mv = frame.moves[i];
      const std::string field = "moves[" + std::to_string(i) + "].id";
      const auto it = slot.find(mv.id);
      if (it == slot.end())
        return fail(report(FormatError{args.frames, line_no, field, "unknown object id " + std::to_string(mv.id)}));
      if (!objects[it->second].dynamic)
        return fail(report(FormatError{args.frames, line_no, field,
                                       "object " + std::to_string(mv.id) + " is static and cannot move"}));
      ObjectDesc& o = objects[it->second];
      o.center = mv.center;
      if (mv.has_rotation && o.shape == Shape::Mesh) o.rotation = mv.rotation;
    }
    // The PVS: the engine runs every frame (its state depends on the frames
    // before), a PVS file is read line by line; both only kept in the slice.
    if (scene) {
      if (!frame.moves.empty()) {
        MoveReport moves;
        if (const Status st = scene->apply_moves(frame.t, frame.moves, &moves); !st.ok)
          return fail(report(FormatError{args.frames, line_no, st.field, st.message}));
      }
      if (const Status st = scene->frame(viewer, frame.camera, frame.t, scratch, &result); !st.ok)
        return fail(report(FormatError{args.frames, line_no, st.field, st.message}));
      pvs = result.pvs;
    } else if (!pvs_in.next(static_cast<std::size_t>(index), slot, &pvs, &message)) {
      return fail(report_message(message));
    }
    if (index < first) {
      ++index;
      continue;
    }
    // Earlier region frames whose horizon holds this frame: checked with
    // the objects where this frame put them.
    for (Checked& c : window) {
      if (!c.waits) continue;
      if (frame.t - c.t > c.camera.horizon_s) {
        c.waits = false;
        continue;
      }
      check_later(&c, objects, index, w, h, args.region_eyes);
      c.waits = index - c.index < args.horizon_frames;
    }
    Checked c;
    c.index = index;
    c.line_no = line_no;
    c.camera = frame.camera;
    c.t = frame.t;
    c.pvs = pvs;
    if (is_region(frame.camera)) {
      // A region: the ray caster's sampling of it (raycast::region_visible),
      // every sighting a double-precision first hit.
      if (!region_noted && !args.quiet) {
        progress.finish();
        const std::string later = args.horizon_frames > 0 ? ", and with the objects of the next " +
                                                                std::to_string(args.horizon_frames) +
                                                                " frames within its horizon"
                                                          : "";
        std::fprintf(stderr, "voxvis: region frames are checked by the CPU ray caster's sampling: %dx%d rays "
                             "a view from the eye box's centre, 8 corners and %d random eyes%s%s\n",
                     w, h, args.region_eyes, frame.camera.omnidirectional ? ", six faces each" : "", later.c_str());
        region_noted = true;
      }
      raycast::RegionSampling sampling;
      sampling.random_eyes = args.region_eyes;
      sampling.rays = raycast::pixel_centres(w, h);
      sampling.seed = static_cast<std::uint64_t>(index) + 1;
      c.vis = raycast::region_visible(objects, frame.camera, sampling);
      std::set_difference(c.vis.begin(), c.vis.end(), c.pvs.begin(), c.pvs.end(), std::back_inserter(c.missed));
      c.waits = args.horizon_frames > 0 && frame.camera.horizon_s > 0.0;
    } else {
      const bool ok = by_egl ? renderer->visible(objects, frame.camera, render::VisibleOptions{w, h, method},
                                                 checks_all ? nullptr : &c.pvs, &c.vis, &c.rs, &message)
                             : raycast_visible(objects, frame.camera, w, h, &c.vis, &c.rs, &message);
      if (!ok) return fail(report(FormatError{args.frames, line_no, "", message}));
      // A miss as report counts one (reference.h): EGL's sightings confirmed
      // in double precision, the edge-only ones dismissed.
      if (!confirm_misses(by_egl ? renderer.get() : nullptr, objects, frame.camera, w, h,
                          method == render::Method::Ids, c.vis, c.pvs, &c.missed, &c.edge_only, &message))
        return fail(report(FormatError{args.frames, line_no, "", message}));
    }
    window.push_back(std::move(c));
    if (!flush(false)) return write_error();
    ++index;
  }
  if (!flush(true)) return write_error();
  if (frames.bad()) return fail(report(FormatError{args.frames, line_no, "", std::string("cannot read: ") + std::strerror(errno)}));
  progress.finish();
  if (args.frame_count > 0 && index < end) {
    return report(FormatError{args.frames, 0, "--frame-count",
                              "asked for frames " + std::to_string(first) + " to " + std::to_string(end - 1) +
                                  ", the file has " + std::to_string(index)});
  }
  if (index < first) {
    return report(FormatError{args.frames, 0, "--first-frame",
                              "is " + std::to_string(first) + ", the file has " + std::to_string(index) + " frames"});
  }
  if (!args.pvs.empty() && args.frame_count < 0 && !pvs_in.at_end()) {
    return report_message(args.pvs + ":" + std::to_string(pvs_in.line()) + ": more PVS lines than frames (" +
                          std::to_string(index) + " frames in " + args.frames + ")");
  }
  if (!out.commit(&message)) return report(FormatError{out.path(), 0, "", message});

  if (!args.quiet) {
    const Spread d = spread(draw_ms), r = spread(read_ms), q = spread(query_ms);
    const std::string dismissed =
        total_edge_only == 0 ? ""
                             : "; " + std::to_string(total_edge_only) +
                                   " edge-only sightings dismissed (EGL's single precision; not visible by the "
                                   "definition)";
    std::fprintf(stderr,
                 "voxvis: verified %llu frames at %dx%d (%s): %llu missed object-frames in %llu frames%s; "
                 "visible %llu, PVS %llu, tightness %.3f; draw ms median %.2f p99 %.2f, queries %.2f, "
                 "read %.2f\n",
                 static_cast<unsigned long long>(verified), w, h, by,
                 static_cast<unsigned long long>(total_missed), static_cast<unsigned long long>(frames_missed),
                 dismissed.c_str(),
                 static_cast<unsigned long long>(total_visible), static_cast<unsigned long long>(total_pvs),
                 total_visible ? static_cast<double>(total_pvs) / static_cast<double>(total_visible) : 0.0,
                 d.median, d.p99, q.median, r.median);
  }
  return total_missed > 0 ? kExitMissed : kExitOk;
}

}  // namespace voxvis::cli
