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

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "cli.h"
#include "common.h"
#include "options.h"
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

/// The flags, checked: the reference's pixels, who computes it, and the
/// renderer's options.
struct ReportFlags {
  int w = 0, h = 0;
  Reference reference = Reference::Auto;
  render::ContextOptions ctx;
};

/// Checks the flags in this order; false, with `error` naming the first bad one.
bool check_report_flags(const ReportArgs& args, ReportFlags* f, FormatError* error) {
  std::string message;
  if (!render::parse_resolution(args.resolution, &f->w, &f->h, &message)) {
    *error = FormatError{"", 0, "--resolution", message};
    return false;
  }
  if (!parse_reference_flags(args.reference, args.egl, &f->reference, &f->ctx, error)) return false;
  if (args.frame_count < -1 || args.frame_count == 0) {
    *error = FormatError{"", 0, "--frame-count", "must be >= 1 (or -1: all)"};
    return false;
  }
  return true;
}

/// The configurations to run, and what their levels need.
struct ReportSweep {
  std::vector<ReportConfig> configs;
  bool has_levels = false;        ///< Some configuration refines (needs EGL).
  bool has_near_optimal = false;  ///< Some configuration needs the GPU's cost model.
};

/// --configs, else the default sweep around the scene's grid; every level
/// checked. On error reports it and returns false.
bool load_report_sweep(const ReportArgs& args, const SceneDesc& desc, const SceneOptions& base, ReportSweep* sweep) {
  std::string message;
  if (!args.configs.empty()) {
    std::string ctext;
    FormatError ferr;
    if (!read_file(args.configs, &ctext, &ferr)) {
      report(ferr);
      return false;
    }
    if (!parse_configs(ctext, args.configs, &sweep->configs, &message)) {
      report_message(message);
      return false;
    }
  } else {
    const glm::ivec3 g = desc.grid ? *desc.grid : Scene::auto_resolution(desc, base);
    sweep->configs = default_configs(g);
  }
  for (std::size_t i = 0; i < sweep->configs.size(); ++i) {
    render::Level l;
    if (!render::parse_level(sweep->configs[i].level, &l, &message)) {
      report_message((args.configs.empty() ? std::string("default configuration") : args.configs) + ": configs[" +
                     std::to_string(i) + "].level: " + message);
      return false;
    }
    sweep->has_levels = sweep->has_levels || l.kind != render::LevelKind::None;
    sweep->has_near_optimal = sweep->has_near_optimal || l.kind == render::LevelKind::NearOptimal;
  }
  return true;
}

/// The frames file's first --frame-count frames (-1: all). On error
/// reports it and returns false.
bool read_report_frames(const ReportArgs& args, std::vector<FrameInput>* frames) {
  std::ifstream in(args.frames, std::ios::binary);
  if (!in) {
    report(FormatError{args.frames, 0, "", std::string("cannot open: ") + std::strerror(errno)});
    return false;
  }
  std::string line;
  int line_no = 0;
  FormatError ferr;
  while (std::getline(in, line) &&
         (args.frame_count < 0 || static_cast<std::int64_t>(frames->size()) < args.frame_count)) {
    ++line_no;
    if (blank(line)) continue;
    FrameInput f;
    if (!parse_frame_line(line, args.frames, line_no, &f, &ferr)) {
      report(ferr);
      return false;
    }
    frames->push_back(std::move(f));
  }
  if (frames->empty()) {
    report(FormatError{args.frames, 0, "", "no frames"});
    return false;
  }
  return true;
}

/// The reference: the exactly visible set of every frame at the pixel
/// centres of w x h, computed once and shared by every configuration. EGL
/// renders it (and runs the refinement levels); the CPU ray caster casts it
/// where no EGL is available, or when asked to.
struct ReportReference {
  std::unique_ptr<render::Renderer> renderer;  ///< Null where EGL is not needed or did not start.
  std::string egl_error;                       ///< Why EGL did not start.
  bool by_egl = false;                         ///< EGL computes the reference.
  std::string summary;                         ///< "WxH (EGL, <GL renderer>)", or the ray caster's.
};

/// Starts EGL where needed, says on stderr who computes the reference, and
/// measures (or loads) near-optimal's cost model now, outside every frame's
/// time. On error reports it and returns false.
bool open_report_reference(const ReportArgs& args, const ReportFlags& f, const ReportSweep& sweep,
                           ReportReference* ref) {
  if (f.reference != Reference::Raycast || sweep.has_levels)
    ref->renderer = render::Renderer::create(f.ctx, &ref->egl_error);
  if (!ref->renderer && f.reference == Reference::Egl) {
    report_message("EGL: " + ref->egl_error);
    return false;
  }
  ref->by_egl = ref->renderer != nullptr && f.reference != Reference::Raycast;
  ref->summary = std::to_string(f.w) + "x" + std::to_string(f.h) + " (" +
                 (ref->by_egl ? "EGL, " + ref->renderer->info().gl_renderer : raycast_summary()) + ")";
  if (!args.quiet) {
    if (!ref->renderer && f.reference == Reference::Auto)
      std::fprintf(stderr, "voxvis: EGL: %s; the exact reference is the CPU ray caster, and refinement levels "
                   "cannot run\n", ref->egl_error.c_str());
    else if (!ref->renderer && sweep.has_levels)
      std::fprintf(stderr, "voxvis: EGL: %s; refinement levels cannot run\n", ref->egl_error.c_str());
    std::fprintf(stderr, "voxvis: exactly visible sets at %s\n", ref->summary.c_str());
  }
  if (ref->renderer && sweep.has_near_optimal) {
    render::CostModel model;
    std::string note, message;
    const std::string path = args.cost_model.empty() ? render::default_cost_model_path() : args.cost_model;
    if (!ref->renderer->cost_model(path, &model, &note, &message)) {
      report_message("the cost model: " + message);
      return false;
    }
    if (!args.quiet) std::fprintf(stderr, "voxvis: near-optimal: %s\n", note.c_str());
  }
  return true;
}

/// One report's measuring: the exactly visible sets, the frustum-culling
/// baseline, then every configuration over the same frames, each judged
/// against the reference.
class ReportRun {
 public:
  ReportRun(const ReportArgs& args, const ReportFlags& flags, const SceneDesc& desc,
            const std::vector<FrameInput>& frames, ReportReference* ref, std::size_t configs)
      : args_(args), f_(flags), desc_(desc), frames_(frames), ref_(*ref), exact_(frames.size()),
        progress_(!args.quiet && ::isatty(STDERR_FILENO) != 0, frames.size() * (configs + 1)) {
    for (std::size_t i = 0; i < desc.objects.size(); ++i) slot_[desc.objects[i].id] = i;
    frustum_.row.name = "frustum culling only";
  }

  /// The reference's exactly visible sets, and the baseline every occlusion
  /// culler has to beat: plain frustum culling of the same frames (each
  /// object's box against the six planes), timed, then judged as every
  /// configuration's output is. kExitOk, or an error's status (reported).
  int measure_reference() {
    std::vector<ObjectDesc> objects = desc_.objects;
    render::VisibleStats vs;
    std::string message;
    for (std::size_t k = 0; k < frames_.size(); ++k) {
      apply(&objects, frames_[k]);
      const Camera& camera = frames_[k].camera;
      const bool ok = ref_.by_egl ? ref_.renderer->visible(objects, camera, render::VisibleOptions{f_.w, f_.h},
                                                           nullptr, &exact_[k], &vs, &message)
                                  : raycast_visible(objects, camera, f_.w, f_.h, &exact_[k], &vs, &message);
      if (!ok) {
        progress_.finish();
        return report(FormatError{args_.frames, frames_[k].line, "", message});
      }
      exact_total_ += exact_[k].size();
      const auto t0 = std::chrono::steady_clock::now();
      const std::vector<ObjectId> in_frustum = raycast::frustum_objects(objects, camera);
      frustum_.ms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
      frustum_.total += in_frustum.size();
      frustum_.sets.push_back(in_frustum);
      progress_.update(++done_);
    }
    objects = desc_.objects;
    for (std::size_t k = 0; k < frames_.size(); ++k) {
      apply(&objects, frames_[k]);
      if (!judge(k, objects, frustum_.sets[k], &frustum_.row, &message))
        return report_message("confirming a miss: " + message);
    }
    return kExitOk;
  }

  /// A configuration's row: its figures, or the error that stopped it.
  ReportRow run_config(const ReportConfig& c, const SceneOptions& base) {
    ReportRow row;
    row.name = c.name;
    render::Level level;
    std::string message;
    render::parse_level(c.level, &level, &message);
    row.may_miss = render::level_may_miss(level);
    SceneOptions opt = base;
    opt.occlusion_buffer = c.occlusion_buffer;
    SceneDesc d = desc_;
    if (c.grid) d.grid = *c.grid;
    std::unique_ptr<Scene> scene;
    if (level.kind != render::LevelKind::None && !ref_.renderer) {
      row.error = "EGL: " + ref_.egl_error;
    } else if (const Status st = Scene::create(d, opt, &scene); !st.ok) {
      row.error = st.str();
    }
    if (!row.error.empty()) {
      done_ += frames_.size();
      return row;
    }
    if (ref_.renderer) ref_.renderer->reset_refinement();  // Each configuration's levels start afresh.
    run_frames(level, scene.get(), &row);
    return row;
  }

  /// The baseline's row; last, after the configurations (report.md sorts by time).
  ReportRow frustum_row() const {
    ReportRow row = frustum_.row;
    const Spread t = spread(frustum_.ms);
    row.frames = frustum_.ms.size();
    row.median_ms = row.engine_ms = t.median;
    row.p99_ms = t.p99;
    row.tightness = tightness(frustum_.total);
    return row;
  }

  void finish() { progress_.finish(); }
  std::uint64_t exact_total() const { return exact_total_; }

 private:
  /// The frustum-culling baseline: its row (misses judged), times and sets.
  struct Baseline {
    ReportRow row;
    std::vector<double> ms;
    std::uint64_t total = 0;
    std::vector<std::vector<ObjectId>> sets;
  };

  /// Puts the frame's moved objects where it says.
  void apply(std::vector<ObjectDesc>* objects, const FrameInput& f) const {
    for (const Move& mv : f.moves) {
      const auto it = slot_.find(mv.id);
      if (it == slot_.end()) continue;
      ObjectDesc& o = (*objects)[it->second];
      o.center = mv.center;
      if (mv.has_rotation && o.shape == Shape::Mesh) o.rotation = mv.rotation;
    }
  }

  /// Output objects over exactly visible ones, over all frames (NaN when
  /// nothing is exactly visible).
  double tightness(std::uint64_t out_total) const {
    return exact_total_ > 0 ? static_cast<double>(out_total) / static_cast<double>(exact_total_) : std::nan("");
  }

  /// Counts frame k's misses in `out` on `row`. A configuration's miss is
  /// verify's (reference.h, confirm_misses): from EGL, a sighting confirmed
  /// in double precision. Each (frame, object) judged once for every
  /// configuration, on a renderer of its own (the refinement levels keep
  /// state in theirs). False, with `message`, when confirming fails.
  bool judge(std::size_t k, const std::vector<ObjectDesc>& objects, const std::vector<ObjectId>& out, ReportRow* row,
             std::string* message) {
    std::vector<ObjectId> sighted, unjudged;
    std::set_difference(exact_[k].begin(), exact_[k].end(), out.begin(), out.end(), std::back_inserter(sighted));
    for (const ObjectId id : sighted)
      if (!verdicts_.count({k, id})) unjudged.push_back(id);
    if (ref_.by_egl && !unjudged.empty()) {
      if (!confirmer_ && !(confirmer_ = render::Renderer::create(f_.ctx, message))) return false;
      std::vector<ObjectId> missed, dismissed;
      if (!confirm_misses(confirmer_.get(), objects, frames_[k].camera, f_.w, f_.h, false, unjudged, {}, &missed,
                          &dismissed, message))
        return false;
      for (const ObjectId id : missed) verdicts_[{k, id}] = true;
      for (const ObjectId id : dismissed) verdicts_[{k, id}] = false;
    }
    for (const ObjectId id : sighted) {
      const bool miss = !ref_.by_egl || verdicts_[{k, id}];
      row->misses += miss ? 1 : 0;
      row->dismissed += miss ? 0 : 1;
    }
    return true;
  }

  /// What a configuration's frames add up to.
  struct ConfigTotals {
    std::vector<double> total_ms, engine_ms;
    std::uint64_t out_total = 0, queries = 0;
  };

  /// Runs the engine, then the level, on every frame, each output judged;
  /// fills the row's figures, or its error.
  void run_frames(const render::Level& level, Scene* scene, ReportRow* row) {
    const ViewerId viewer = scene->add_viewer();
    Scratch scratch;
    FrameResult fr;
    std::vector<ObjectDesc> objects = desc_.objects;
    ConfigTotals totals;
    std::vector<ObjectId> out;
    std::string message;
    for (std::size_t k = 0; k < frames_.size() && row->error.empty(); ++k) {
      const FrameInput& f = frames_[k];
      apply(&objects, f);
      Status st;
      if (!f.moves.empty()) st = scene->apply_moves(f.t, f.moves);
      if (st.ok) st = scene->frame(viewer, f.camera, f.t, scratch, &fr);
      if (!st.ok) {
        row->error = args_.frames + ":" + std::to_string(f.line) + ": " + st.str();
        break;
      }
      double refine_ms = 0.0;
      if (level.kind == render::LevelKind::None) {
        out = fr.pvs;
      } else if (!refine(level, objects, f.camera, fr.pvs, &out, row, &refine_ms, &totals.queries, &message)) {
        row->error = message;
        break;
      }
      totals.engine_ms.push_back(fr.stats.time_us / 1000.0);
      totals.total_ms.push_back(fr.stats.time_us / 1000.0 + refine_ms);
      totals.out_total += out.size();
      if (!judge(k, objects, out, row, &message)) {
        row->error = "confirming a miss: " + message;
        break;
      }
      progress_.update(++done_);
    }
    if (row->error.empty()) fill_figures(totals, row);
  }

  /// The level's pass over the engine's PVS; its costs go on the row (sums
  /// until fill_figures). False, with `message`, when it fails.
  bool refine(const render::Level& level, const std::vector<ObjectDesc>& objects, const Camera& camera,
              const std::vector<ObjectId>& pvs, std::vector<ObjectId>* out, ReportRow* row, double* refine_ms,
              std::uint64_t* queries, std::string* message) {
    render::RefineStats rs;
    if (!ref_.renderer->refine(level, objects, camera, f_.w, f_.h, pvs, out, &rs, message)) return false;
    *refine_ms = rs.draw_ms + rs.query_ms + rs.wait_ms;
    *queries += rs.queries;
    row->draw_calls += rs.draw_calls;
    row->pixels += static_cast<double>(rs.pixels);
    row->draw_ms += rs.draw_ms;
    row->query_ms += rs.query_ms;
    row->wait_ms += rs.wait_ms;
    return true;
  }

  /// The row's times, tightness, and per-frame means of the level's costs.
  void fill_figures(const ConfigTotals& totals, ReportRow* row) const {
    row->frames = totals.total_ms.size();
    const Spread t = spread(totals.total_ms), e = spread(totals.engine_ms);
    row->median_ms = t.median;
    row->p99_ms = t.p99;
    row->engine_ms = e.median;
    row->tightness = tightness(totals.out_total);
    const double per = 1.0 / static_cast<double>(std::max<std::size_t>(row->frames, 1));
    row->queries = static_cast<double>(totals.queries) * per;
    for (double* v : {&row->draw_calls, &row->pixels, &row->draw_ms, &row->query_ms, &row->wait_ms}) *v *= per;
  }

  const ReportArgs& args_;
  const ReportFlags& f_;
  const SceneDesc& desc_;
  const std::vector<FrameInput>& frames_;
  ReportReference& ref_;
  std::unordered_map<ObjectId, std::size_t> slot_;  ///< id -> index in the scene's objects.
  std::vector<std::vector<ObjectId>> exact_;        ///< Every frame's exactly visible set.
  std::uint64_t exact_total_ = 0;
  Baseline frustum_;
  std::unique_ptr<render::Renderer> confirmer_;
  std::map<std::pair<std::size_t, ObjectId>, bool> verdicts_;  ///< true: a miss.
  Progress progress_;
  std::size_t done_ = 0;
};

/// report.json's document.
nlohmann::json report_document(const ReportArgs& args, std::size_t frames, const ReportReference& ref,
                               std::uint64_t exact_total, const std::vector<ReportConfig>& configs,
                               const std::vector<ReportRow>& rows) {
  nlohmann::json j;
  j["format"] = "voxvis-report/1";
  j["scene"] = args.scene;
  j["frames"] = frames;
  j["reference"] = ref.summary;
  j["reference_source"] = ref.by_egl ? "egl" : "raycast";
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
  return j;
}

/// The plot's data files: name, time and tightness of the conservative rows
/// (tradeoff.dat), of the rows that miss (missing.dat), and of the Pareto
/// front by time (pareto.dat).
struct PlotData {
  std::string data, front, missing;
};

PlotData plot_data(const std::vector<ReportRow>& rows) {
  PlotData plot;
  std::vector<const ReportRow*> pareto;
  for (const ReportRow& r : rows) {
    if (!r.error.empty() || !std::isfinite(r.tightness)) continue;
    char buf[512];
    std::snprintf(buf, sizeof buf, "%s\t%.6g\t%.6g\n", r.name.c_str(), std::max(r.median_ms, 1e-3), r.tightness);
    (r.misses > 0 ? plot.missing : plot.data) += buf;
    if (r.pareto) pareto.push_back(&r);
  }
  std::sort(pareto.begin(), pareto.end(), [](const ReportRow* a, const ReportRow* b) { return a->median_ms < b->median_ms; });
  for (const ReportRow* r : pareto) {
    char buf[512];
    std::snprintf(buf, sizeof buf, "%s\t%.6g\t%.6g\n", r->name.c_str(), std::max(r->median_ms, 1e-3), r->tightness);
    plot.front += buf;
  }
  return plot;
}

/// report.json, report.md, the plot's data files and tradeoff.gp; false,
/// with `message`, at the first that cannot be written.
bool write_report_files(const std::filesystem::path& dir, const std::string& title, const nlohmann::json& document,
                        const std::vector<ReportRow>& rows, const std::string& reference, const PlotData& plot,
                        std::string* message) {
  return write_text(dir / "report.json", document.dump(2) + "\n", message) &&
         write_text(dir / "report.md", "# voxvis report: " + title + "\n\n" + report_markdown(rows, reference),
                    message) &&
         write_text(dir / "tradeoff.dat", plot.data, message) && write_text(dir / "pareto.dat", plot.front, message) &&
         write_text(dir / "missing.dat", plot.missing, message) &&
         write_text(dir / "tradeoff.gp",
                    plot_script(title, !plot.data.empty(), !plot.front.empty(), !plot.missing.empty()), message);
}

/// Draws tradeoff.png where some row has a tightness; kExitError (said on
/// stderr) when gnuplot fails.
int draw_tradeoff_plot(const std::filesystem::path& dir, const PlotData& plot) {
  if (plot.data.empty() && plot.missing.empty()) {
    std::fprintf(stderr, "voxvis: no plot: no configuration has a tightness (none ran, or nothing is exactly "
                 "visible on these frames)\n");
    return kExitOk;
  }
  std::string why;
  if (!run_gnuplot(dir, &why)) {
    std::fprintf(stderr, "voxvis: error: %s/tradeoff.png: %s (report.json and report.md are written)\n",
                 dir.string().c_str(), why.c_str());
    return kExitError;
  }
  return kExitOk;
}

/// Says on stderr why each failed configuration could not run; how many.
std::size_t report_failed_configs(const std::vector<ReportRow>& rows) {
  std::size_t failed = 0;
  for (const ReportRow& r : rows)
    if (!r.error.empty()) {
      ++failed;
      std::fprintf(stderr, "voxvis: error: configuration '%s' could not run: %s\n", r.name.c_str(), r.error.c_str());
    }
  return failed;
}

}  // namespace

int run_report(const ReportArgs& args) {
  ReportFlags flags;
  FormatError flag_error;
  if (!check_report_flags(args, &flags, &flag_error)) return report(flag_error);
  EngineArgs engine;
  engine.scene = args.scene;
  std::string text;
  SceneDesc desc;
  SceneOptions base;
  int code = kExitOk;
  if (!load_scene(engine, &text, &desc, &base, &code)) return code;
  ReportSweep sweep;
  if (!load_report_sweep(args, desc, base, &sweep)) return kExitError;
  std::vector<FrameInput> frames;
  if (!read_report_frames(args, &frames)) return kExitError;
  std::error_code ec;
  const std::filesystem::path dir(args.out);
  std::filesystem::create_directories(dir, ec);
  if (ec) return report(FormatError{args.out, 0, "--out", "cannot create the directory: " + ec.message()});
  ReportReference ref;
  if (!open_report_reference(args, flags, sweep, &ref)) return kExitError;

  ReportRun run(args, flags, desc, frames, &ref, sweep.configs.size());
  if (const int status = run.measure_reference(); status != kExitOk) return status;
  std::vector<ReportRow> rows;
  for (const ReportConfig& c : sweep.configs) rows.push_back(run.run_config(c, base));
  rows.push_back(run.frustum_row());
  run.finish();
  mark_pareto(&rows);

  const std::string title = std::filesystem::path(args.scene).filename().string() + ", " +
                            std::to_string(frames.size()) + " frames, exact at " + ref.summary;
  const PlotData plot = plot_data(rows);
  std::string message;
  if (!write_report_files(dir, title, report_document(args, frames.size(), ref, run.exact_total(), sweep.configs, rows),
                          rows, ref.summary, plot, &message))
    return report_message(message);
  const int status = draw_tradeoff_plot(dir, plot);
  const std::size_t failed = report_failed_configs(rows);
  if (!args.quiet)
    std::fprintf(stderr, "voxvis: %zu configurations on %zu frames (%zu failed); wrote %s/report.md, report.json, "
                 "tradeoff.png\n", rows.size(), frames.size(), failed, dir.string().c_str());
  return failed > 0 ? kExitError : status;
}

Command add_report_command(CLI::App& app) {
  auto args = std::make_shared<ReportArgs>();
  CLI::App* cmd = app.add_subcommand(
      "report", "Run every configuration on the same frames: time per frame against tightness and misses.");
  cmd->add_option("--scene", args->scene, "Scene file (JSON, format voxvis-scene/1)")->required()->type_name("FILE");
  cmd->add_option("--frames", args->frames, "Frames file (JSON Lines)")->required()->type_name("FILE");
  cmd->add_option("--configs", args->configs, "Configurations (JSON); default: the standard sweep")
      ->type_name("FILE");
  cmd->add_option("--out", args->out, "Output directory: report.json, report.md, tradeoff.png")
      ->type_name("DIR")
      ->capture_default_str();
  cmd->add_option("--resolution", args->resolution, "Pixels of the exact reference and of the levels")
      ->type_name("WxH")
      ->capture_default_str();
  cmd->add_option("--reference", args->reference,
                  "Who finds the exactly visible sets at the pixel centres: egl (the headless renderer), "
                  "raycast (the CPU ray caster), auto (EGL when a context starts, else the ray caster); "
                  "refinement levels need EGL either way")
      ->type_name("auto|egl|raycast")
      ->capture_default_str();
  cmd->add_option("--cost-model", args->cost_model,
                  "near-optimal's model of the GPU: loaded from FILE, else measured and saved there "
                  "(default: $XDG_CACHE_HOME/voxvis/cost-model.json, else ~/.cache/voxvis/)")
      ->type_name("FILE");
  cmd->add_option("--frame-count", args->frame_count, "Use the first N frames; -1: all")
      ->type_name("N")
      ->capture_default_str();
  add_egl_options(cmd, &args->egl);
  cmd->add_flag("-q,--quiet", args->quiet, "No progress bar or summary on stderr");
  return {cmd, [args] { return run_report(*args); }};
}

}  // namespace voxvis::cli
