// report_cmd.cpp — `voxvis report`: every configuration on the same frames,
// time per frame next to tightness and misses against the exactly visible
// set (EGL's, or the CPU ray caster's where no EGL is available), as
// report.json, report.md and tradeoff.png (docs/accuracy.md).
#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <string>
#include <unordered_map>
#include <vector>

#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <nlohmann/json.hpp>

#include "cli.h"
#include "common.h"
#include "reference.h"
#include "report_model.h"
#include "voxvis/format.h"
#include "voxvis/raycast.h"
#include "voxvis/refine.h"
#include "voxvis/render.h"
#include "voxvis/scene.h"

extern char** environ;

namespace voxvis::cli {
namespace {

bool write_text(const std::filesystem::path& p, const std::string& text, std::string* message) {
  std::ofstream f(p, std::ios::binary | std::ios::trunc);
  f << text;
  f.close();
  if (!f) {
    *message = p.string() + ": cannot write: " + std::strerror(errno);
    return false;
  }
  return true;
}

/// The gnuplot script of the trade-off plot: tightness against time per
/// frame on log axes, every point labelled, the Pareto front drawn, the
/// configurations that miss visible objects apart. Empty data files are left
/// out (gnuplot refuses them).
std::string plot_script(const std::string& title, bool conservative, bool front, bool missing) {
  std::vector<std::string> parts;
  if (conservative) {
    parts.push_back("'tradeoff.dat' using 2:3 with points pt 7 ps 1.2 lc rgb '#3060a0' title 'conservative'");
    parts.push_back("'' using 2:3:1 with labels offset 0.8,0.6 left font 'sans,8' noenhanced notitle");
  }
  if (missing) {
    parts.push_back("'missing.dat' using 2:3 with points pt 2 ps 1.4 lc rgb '#c07000' title 'misses visible objects'");
    parts.push_back("'' using 2:3:1 with labels offset 0.8,-0.6 left font 'sans,8' noenhanced notitle");
  }
  if (front) parts.push_back("'pareto.dat' using 2:3 with lines lw 2 lc rgb '#c03030' title 'Pareto front'");
  std::string plot = "plot ";
  for (std::size_t i = 0; i < parts.size(); ++i) plot += (i ? ", \\\n     " : "") + parts[i];
  return "set terminal pngcairo size 1100,750 font 'sans,10'\n"
         "set output 'tradeoff.png'\n"
         "set title '" + title + "' noenhanced\n"
         "set logscale xy\n"
         "set xlabel 'time per frame, ms (median; engine + refinement)'\n"
         "set ylabel 'tightness (PVS / exactly visible)'\n"
         "set grid\n"
         "set key top right\n"
         "set offsets graph 0.02, graph 0.3, 0, 0\n"
         "set datafile separator '\\t'\n" + plot + "\n";
}

/// Runs `gnuplot tradeoff.gp` in `dir` (no shell: any directory name is
/// safe); on failure says why.
bool run_gnuplot(const std::filesystem::path& dir, std::string* why) {
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addchdir_np(&actions, dir.c_str());
  char prog[] = "gnuplot", script[] = "tradeoff.gp";
  char* argv[] = {prog, script, nullptr};
  pid_t pid = 0;
  const int rc = posix_spawnp(&pid, "gnuplot", &actions, nullptr, argv, environ);
  posix_spawn_file_actions_destroy(&actions);
  if (rc != 0) {
    *why = std::string("cannot run gnuplot: ") + std::strerror(rc) + " (install gnuplot-nox)";
    return false;
  }
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    *why = "gnuplot failed (exit " + std::to_string(WIFEXITED(status) ? WEXITSTATUS(status) : -1) + ")";
    return false;
  }
  return true;
}

}  // namespace

int run_report(const ReportArgs& args) {
  std::string message;
  int w = 0, h = 0;
  if (!render::parse_resolution(args.resolution, &w, &h, &message)) return report(FormatError{"", 0, "--resolution", message});
  Reference reference_kind = Reference::Auto;
  render::ContextOptions ctx;
  FormatError flag_error;
  if (!parse_reference_flags(args.reference, args.egl, &reference_kind, &ctx, &flag_error)) return report(flag_error);
  if (args.frame_count < -1 || args.frame_count == 0)
    return report(FormatError{"", 0, "--frame-count", "must be >= 1 (or -1: all)"});

  EngineArgs engine;
  engine.scene = args.scene;
  std::string text;
  SceneDesc desc;
  SceneOptions base;
  int code = kExitOk;
  if (!load_scene(engine, &text, &desc, &base, &code)) return code;

  std::vector<ReportConfig> configs;
  if (!args.configs.empty()) {
    std::string ctext;
    FormatError ferr;
    if (!read_file(args.configs, &ctext, &ferr)) return report(ferr);
    if (!parse_configs(ctext, args.configs, &configs, &message)) return report_message(message);
  } else {
    const glm::ivec3 g = desc.grid ? *desc.grid : Scene::auto_resolution(desc, base);
    configs = default_configs(g);
  }
  bool has_levels = false, has_near_optimal = false;
  for (std::size_t i = 0; i < configs.size(); ++i) {
    render::Level l;
    if (!render::parse_level(configs[i].level, &l, &message))
      return report_message((args.configs.empty() ? std::string("default configuration") : args.configs) +
                            ": configs[" + std::to_string(i) + "].level: " + message);
    has_levels = has_levels || l.kind != render::LevelKind::None;
    has_near_optimal = has_near_optimal || l.kind == render::LevelKind::NearOptimal;
  }

  // The frames.
  std::ifstream in(args.frames, std::ios::binary);
  if (!in) return report(FormatError{args.frames, 0, "", std::string("cannot open: ") + std::strerror(errno)});
  std::vector<FrameInput> frames;
  {
    std::string line;
    int line_no = 0;
    FormatError ferr;
    while (std::getline(in, line) &&
           (args.frame_count < 0 || static_cast<std::int64_t>(frames.size()) < args.frame_count)) {
      ++line_no;
      if (blank(line)) continue;
      FrameInput f;
      if (!parse_frame_line(line, args.frames, line_no, &f, &ferr)) return report(ferr);
      frames.push_back(std::move(f));
    }
  }
  if (frames.empty()) return report(FormatError{args.frames, 0, "", "no frames"});

  std::error_code ec;
  const std::filesystem::path dir(args.out);
  std::filesystem::create_directories(dir, ec);
  if (ec) return report(FormatError{args.out, 0, "--out", "cannot create the directory: " + ec.message()});

  // The reference: the exactly visible set of every frame at the pixel
  // centres of w x h, computed once here and shared by every configuration.
  // EGL renders it (and runs the refinement levels); the CPU ray caster
  // casts it where no EGL is available, or when asked to.
  std::string egl_error;
  std::unique_ptr<render::Renderer> renderer;
  if (reference_kind != Reference::Raycast || has_levels) renderer = render::Renderer::create(ctx, &egl_error);
  if (!renderer && reference_kind == Reference::Egl) return report_message("EGL: " + egl_error);
  const bool by_egl = renderer != nullptr && reference_kind != Reference::Raycast;
  const std::string reference = std::to_string(w) + "x" + std::to_string(h) + " (" +
                                (by_egl ? "EGL, " + renderer->info().gl_renderer : raycast_summary()) + ")";
  if (!args.quiet) {
    if (!renderer && reference_kind == Reference::Auto)
      std::fprintf(stderr, "voxvis: EGL: %s; the exact reference is the CPU ray caster, and refinement levels "
                   "cannot run\n", egl_error.c_str());
    else if (!renderer && has_levels)
      std::fprintf(stderr, "voxvis: EGL: %s; refinement levels cannot run\n", egl_error.c_str());
    std::fprintf(stderr, "voxvis: exactly visible sets at %s\n", reference.c_str());
  }
  if (renderer && has_near_optimal) {
    // Measured (or loaded) now, outside every frame's time.
    render::CostModel model;
    std::string note;
    const std::string path = args.cost_model.empty() ? render::default_cost_model_path() : args.cost_model;
    if (!renderer->cost_model(path, &model, &note, &message)) return report_message("the cost model: " + message);
    if (!args.quiet) std::fprintf(stderr, "voxvis: near-optimal: %s\n", note.c_str());
  }
  std::unordered_map<ObjectId, std::size_t> slot;
  for (std::size_t i = 0; i < desc.objects.size(); ++i) slot[desc.objects[i].id] = i;
  auto apply = [&](std::vector<ObjectDesc>* objects, const FrameInput& f) {
    for (const Move& mv : f.moves) {
      const auto it = slot.find(mv.id);
      if (it == slot.end()) continue;
      ObjectDesc& o = (*objects)[it->second];
      o.center = mv.center;
      if (mv.has_rotation && o.shape == Shape::Mesh) o.rotation = mv.rotation;
    }
  };
  std::vector<std::vector<ObjectId>> exact(frames.size());
  std::uint64_t exact_total = 0;
  // The baseline every occlusion culler has to beat: plain frustum culling
  // of the same frames (each object's box against the six planes).
  ReportRow frustum;
  frustum.name = "frustum culling only";
  std::vector<double> frustum_ms;
  std::uint64_t frustum_total = 0;
  std::vector<std::vector<ObjectId>> frustum_sets;  // Judged below, as every configuration's output.
  Progress progress(!args.quiet && ::isatty(STDERR_FILENO) != 0, frames.size() * (configs.size() + 1));
  std::size_t done = 0;
  {
    std::vector<ObjectDesc> objects = desc.objects;
    render::VisibleStats vs;
    for (std::size_t k = 0; k < frames.size(); ++k) {
      apply(&objects, frames[k]);
      const bool ok = by_egl ? renderer->visible(objects, frames[k].camera, render::VisibleOptions{w, h}, nullptr,
                                                 &exact[k], &vs, &message)
                             : raycast_visible(objects, frames[k].camera, w, h, &exact[k], &vs, &message);
      if (!ok) {
        progress.finish();
        return report(FormatError{args.frames, frames[k].line, "", message});
      }
      exact_total += exact[k].size();
      const auto t0 = std::chrono::steady_clock::now();
      const std::vector<ObjectId> in_frustum = raycast::frustum_objects(objects, frames[k].camera);
      frustum_ms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
      frustum_total += in_frustum.size();
      frustum_sets.push_back(in_frustum);
      progress.update(++done);
    }
  }

  // A configuration's miss is verify's (reference.h, confirm_misses): from
  // EGL, a sighting confirmed in double precision. Each (frame, object)
  // judged once for every configuration, on a renderer of its own (the
  // refinement levels keep state in theirs).
  std::unique_ptr<render::Renderer> confirmer;
  std::map<std::pair<std::size_t, ObjectId>, bool> verdicts;  // true: a miss.
  auto judge = [&](std::size_t k, const std::vector<ObjectDesc>& objects, const std::vector<ObjectId>& out,
                   ReportRow* row) {
    std::vector<ObjectId> sighted, unjudged;
    std::set_difference(exact[k].begin(), exact[k].end(), out.begin(), out.end(), std::back_inserter(sighted));
    for (const ObjectId id : sighted)
      if (!verdicts.count({k, id})) unjudged.push_back(id);
    if (by_egl && !unjudged.empty()) {
      if (!confirmer && !(confirmer = render::Renderer::create(ctx, &message))) return false;
      std::vector<ObjectId> missed, dismissed;
      if (!confirm_misses(confirmer.get(), objects, frames[k].camera, w, h, false, unjudged, {}, &missed, &dismissed,
                          &message))
        return false;
      for (const ObjectId id : missed) verdicts[{k, id}] = true;
      for (const ObjectId id : dismissed) verdicts[{k, id}] = false;
    }
    for (const ObjectId id : sighted) {
      const bool miss = !by_egl || verdicts[{k, id}];
      row->misses += miss ? 1 : 0;
      row->dismissed += miss ? 0 : 1;
    }
    return true;
  };

  {
    std::vector<ObjectDesc> objects = desc.objects;
    for (std::size_t k = 0; k < frames.size(); ++k) {
      apply(&objects, frames[k]);
      if (!judge(k, objects, frustum_sets[k], &frustum)) return report_message("confirming a miss: " + message);
    }
  }

  std::vector<ReportRow> rows;
  for (const ReportConfig& c : configs) {
    ReportRow row;
    row.name = c.name;
    render::Level level;
    render::parse_level(c.level, &level, &message);
    row.may_miss = render::level_may_miss(level);
    SceneOptions opt = base;
    opt.occlusion_buffer = c.occlusion_buffer;
    SceneDesc d = desc;
    if (c.grid) d.grid = *c.grid;
    std::unique_ptr<Scene> scene;
    if (level.kind != render::LevelKind::None && !renderer) {
      row.error = "EGL: " + egl_error;
    } else if (const Status st = Scene::create(d, opt, &scene); !st.ok) {
      row.error = st.str();
    }
    if (!row.error.empty()) {
      rows.push_back(row);
      done += frames.size();
      continue;
    }
    if (renderer) renderer->reset_refinement();  // Each configuration's levels start afresh.
    const ViewerId viewer = scene->add_viewer();
    Scratch scratch;
    FrameResult fr;
    std::vector<ObjectDesc> objects = desc.objects;
    std::vector<double> total_ms, engine_ms;
    std::uint64_t out_total = 0, queries = 0;
    std::vector<ObjectId> out;
    for (std::size_t k = 0; k < frames.size() && row.error.empty(); ++k) {
      const FrameInput& f = frames[k];
      apply(&objects, f);
      if (!f.moves.empty()) {
        if (const Status st = scene->apply_moves(f.t, f.moves); !st.ok) {
          row.error = args.frames + ":" + std::to_string(f.line) + ": " + st.str();
          break;
        }
      }
      if (const Status st = scene->frame(viewer, f.camera, f.t, scratch, &fr); !st.ok) {
        row.error = args.frames + ":" + std::to_string(f.line) + ": " + st.str();
        break;
      }
      double refine_ms = 0.0;
      if (level.kind == render::LevelKind::None) {
        out = fr.pvs;
      } else {
        render::RefineStats rs;
        if (!renderer->refine(level, objects, f.camera, w, h, fr.pvs, &out, &rs, &message)) {
          row.error = message;
          break;
        }
        refine_ms = rs.draw_ms + rs.query_ms + rs.wait_ms;
        queries += rs.queries;
        row.draw_calls += rs.draw_calls;
        row.pixels += static_cast<double>(rs.pixels);
        row.draw_ms += rs.draw_ms;
        row.query_ms += rs.query_ms;
        row.wait_ms += rs.wait_ms;
      }
      engine_ms.push_back(fr.stats.time_us / 1000.0);
      total_ms.push_back(fr.stats.time_us / 1000.0 + refine_ms);
      out_total += out.size();
      if (!judge(k, objects, out, &row)) {
        row.error = "confirming a miss: " + message;
        break;
      }
      progress.update(++done);
    }
    if (row.error.empty()) {
      row.frames = total_ms.size();
      const Spread t = spread(total_ms), e = spread(engine_ms);
      row.median_ms = t.median;
      row.p99_ms = t.p99;
      row.engine_ms = e.median;
      row.tightness =
          exact_total > 0 ? static_cast<double>(out_total) / static_cast<double>(exact_total) : std::nan("");
      const double per = 1.0 / static_cast<double>(std::max<std::size_t>(row.frames, 1));
      row.queries = static_cast<double>(queries) * per;
      for (double* v : {&row.draw_calls, &row.pixels, &row.draw_ms, &row.query_ms, &row.wait_ms}) *v *= per;
    }
    rows.push_back(row);
  }
  {  // Last, after the configurations (report.md sorts by time).
    const Spread t = spread(frustum_ms);
    frustum.frames = frustum_ms.size();
    frustum.median_ms = frustum.engine_ms = t.median;
    frustum.p99_ms = t.p99;
    frustum.tightness =
        exact_total > 0 ? static_cast<double>(frustum_total) / static_cast<double>(exact_total) : std::nan("");
    rows.push_back(frustum);
  }
  progress.finish();
  mark_pareto(&rows);

  // report.json, report.md, tradeoff.dat / pareto.dat / tradeoff.gp and the plot.
  nlohmann::json j;
  j["format"] = "voxvis-report/1";
  j["scene"] = args.scene;
  j["frames"] = frames.size();
  j["reference"] = reference;
  j["reference_source"] = by_egl ? "egl" : "raycast";
  j["exactly_visible_total"] = exact_total;
  for (std::size_t i = 0; i < rows.size(); ++i) {
    const ReportRow& r = rows[i];
    nlohmann::json e;
    e["name"] = r.name;
    if (i < configs.size()) {
      e["level"] = configs[i].level;
      e["occlusion_buffer"] = configs[i].occlusion_buffer;
      if (configs[i].grid) e["grid"] = {configs[i].grid->x, configs[i].grid->y, configs[i].grid->z};
    } else {
      e["baseline"] = "frustum";  // The last row: plain frustum culling, no engine.
    }
    if (!r.error.empty()) {
      e["error"] = r.error;
    } else {
      e["frames"] = r.frames;
      e["median_ms"] = r.median_ms;
      e["p99_ms"] = r.p99_ms;
      e["engine_median_ms"] = r.engine_ms;
      e["tightness"] = std::isfinite(r.tightness) ? nlohmann::json(r.tightness) : nlohmann::json(nullptr);
      e["misses"] = r.misses;
      e["edge_only_dismissed"] = r.dismissed;
      e["may_miss"] = r.may_miss;
      e["queries_per_frame"] = r.queries;
      e["refinement"] = {{"draw_calls_per_frame", r.draw_calls}, {"samples_passed_per_frame", r.pixels},
                         {"draw_ms_mean", r.draw_ms},           {"query_ms_mean", r.query_ms},
                         {"wait_ms_mean", r.wait_ms}};
      e["pareto"] = r.pareto;
    }
    j["rows"].push_back(e);
  }
  std::string data, front, missing;
  std::vector<const ReportRow*> pareto;
  for (const ReportRow& r : rows) {
    if (!r.error.empty() || !std::isfinite(r.tightness)) continue;
    char buf[512];
    std::snprintf(buf, sizeof buf, "%s\t%.6g\t%.6g\n", r.name.c_str(), std::max(r.median_ms, 1e-3), r.tightness);
    (r.misses > 0 ? missing : data) += buf;
    if (r.pareto) pareto.push_back(&r);
  }
  std::sort(pareto.begin(), pareto.end(), [](const ReportRow* a, const ReportRow* b) { return a->median_ms < b->median_ms; });
  for (const ReportRow* r : pareto) {
    char buf[512];
    std::snprintf(buf, sizeof buf, "%s\t%.6g\t%.6g\n", r->name.c_str(), std::max(r->median_ms, 1e-3), r->tightness);
    front += buf;
  }
  const std::string title = std::filesystem::path(args.scene).filename().string() + ", " +
                            std::to_string(frames.size()) + " frames, exact at " + reference;
  if (!write_text(dir / "report.json", j.dump(2) + "\n", &message) ||
      !write_text(dir / "report.md", "# voxvis report: " + title + "\n\n" + report_markdown(rows, reference), &message) ||
      !write_text(dir / "tradeoff.dat", data, &message) || !write_text(dir / "pareto.dat", front, &message) ||
      !write_text(dir / "missing.dat", missing, &message) ||
      !write_text(dir / "tradeoff.gp", plot_script(title, !data.empty(), !front.empty(), !missing.empty()), &message))
    return report_message(message);
  int status = kExitOk;
  if (data.empty() && missing.empty()) {
    std::fprintf(stderr, "voxvis: no plot: no configuration has a tightness (none ran, or nothing is exactly "
                 "visible on these frames)\n");
  } else {
    std::string why;
    if (!run_gnuplot(dir, &why)) {
      std::fprintf(stderr, "voxvis: error: %s/tradeoff.png: %s (report.json and report.md are written)\n",
                   dir.string().c_str(), why.c_str());
      status = kExitError;
    }
  }
  std::size_t failed = 0;
  for (const ReportRow& r : rows)
    if (!r.error.empty()) {
      ++failed;
      std::fprintf(stderr, "voxvis: error: configuration '%s' could not run: %s\n", r.name.c_str(), r.error.c_str());
    }
  if (!args.quiet)
    std::fprintf(stderr, "voxvis: %zu configurations on %zu frames (%zu failed); wrote %s/report.md, report.json, "
                 "tradeoff.png\n", rows.size(), frames.size(), failed, dir.string().c_str());
  return failed > 0 ? kExitError : status;
}

}  // namespace voxvis::cli
