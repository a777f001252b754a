// cost_model.cpp — near-optimal's model of the GPU (voxvis/refine.h
// CostModel), after Guthe et al. section 3.2: the times of a draw call, a
// triangle and a fragment, of a query's setup and fragments, its latency and
// its overhead around a draw, measured on the renderer's own context with its
// own pipeline (the exact-object shader on box proxies), and kept in a JSON
// file per device so that later runs skip the measuring.
#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "renderer_impl.h"
#include "voxvis/refine.h"

namespace voxvis::render {

using detail::Basis;
using detail::Clock;
using detail::ms_since;

double CostModel::render_ms(double triangles, double fragments) const {
  return std::max({render_setup_us * 1e-3, triangles * render_triangle_ns * 1e-6, fragments * render_fragment_ns * 1e-6});
}

double CostModel::query_ms(double fragments) const {
  return query_setup_us * 1e-3 + fragments * query_fragment_ns * 1e-6;
}

std::string default_cost_model_path() {
  const char* xdg = std::getenv("XDG_CACHE_HOME");
  if (xdg != nullptr && xdg[0] == '/') return std::string(xdg) + "/voxvis/cost-model.json";
  const char* home = std::getenv("HOME");
  if (home != nullptr && home[0] == '/') return std::string(home) + "/.cache/voxvis/cost-model.json";
  return "";
}

namespace {

constexpr const char* kFormat = "voxvis-cost-model";

nlohmann::json to_json(const CostModel& c) {
  return {{"device", c.device},
          {"render_setup_us", c.render_setup_us},
          {"render_triangle_ns", c.render_triangle_ns},
          {"render_fragment_ns", c.render_fragment_ns},
          {"query_setup_us", c.query_setup_us},
          {"query_fragment_ns", c.query_fragment_ns},
          {"query_latency_us", c.query_latency_us},
          {"query_overhead_us", c.query_overhead_us},
          {"calibration_ms", c.calibration_ms}};
}

/// The model for `device` in a file's JSON; false when there is none or it
/// is not a well-formed one (every time finite and >= 0).
bool from_json(const nlohmann::json& file, const std::string& device, CostModel* out) {
  if (!file.is_object() || file.value("format", "") != kFormat || !file.contains("models") ||
      !file["models"].is_array())
    return false;
  for (const nlohmann::json& e : file["models"]) {
    if (!e.is_object() || !e.contains("device") || !e["device"].is_string() || e["device"] != device) continue;
    CostModel c;
    c.device = device;
    const std::pair<const char*, double*> fields[] = {
        {"render_setup_us", &c.render_setup_us},     {"render_triangle_ns", &c.render_triangle_ns},
        {"render_fragment_ns", &c.render_fragment_ns}, {"query_setup_us", &c.query_setup_us},
        {"query_fragment_ns", &c.query_fragment_ns}, {"query_latency_us", &c.query_latency_us},
        {"query_overhead_us", &c.query_overhead_us}, {"calibration_ms", &c.calibration_ms}};
    for (const auto& [name, value] : fields) {
      if (!e.contains(name) || !e[name].is_number()) return false;
      *value = e[name].get<double>();
      if (!std::isfinite(*value) || *value < 0.0) return false;
    }
    *out = c;
    return true;
  }
  return false;
}

/// Median of `reps` runs of `f` (each ending in glFinish), milliseconds.
double median_ms(int reps, const std::function<void()>& f) {
  std::vector<double> t;
  for (int r = 0; r < reps; ++r) {
    glFinish();
    const auto t0 = Clock::now();
    f();
    glFinish();
    t.push_back(ms_since(t0));
  }
  std::nth_element(t.begin(), t.begin() + reps / 2, t.end());
  return t[static_cast<std::size_t>(reps / 2)];
}

}  // namespace

bool Renderer::Impl::ensure_model(std::string* note, std::string* error) {
  note->clear();
  if (refine.model) return true;
  if (!refine.model_path_set) {
    refine.model_path = default_cost_model_path();
    refine.model_path_set = true;
  }
  // Query costs depend on how results are read: a model measured one query
  // at a time (before query buffers) is not this one's.
  const std::string device =
      info.gl_renderer + " | " + info.gl_version + (info.query_buffer ? " | query buffer" : "");
  const std::string& path = refine.model_path;
  nlohmann::json file;
  std::string unreadable;
  if (!path.empty()) {
    std::ifstream in(path);
    if (in) {
      file = nlohmann::json::parse(in, nullptr, false);
      if (file.is_discarded()) {
        unreadable = path + " is not valid JSON";
        file = nlohmann::json();
      }
      CostModel c;
      if (from_json(file, device, &c)) {
        refine.model = std::make_unique<CostModel>(c);
        *note = "cost model loaded from " + path;
        return true;
      }
    }
  }

  // Measure at 640x360 with the camera at the origin looking down -z: a
  // box of about one pixel at 10 units, and a box filling the view.
  constexpr int kW = 640, kH = 360;
  Camera cam;
  cam.eye = Vec3(0.0);
  cam.dir = Vec3(0.0, 0.0, -1.0);
  cam.up = Vec3(0.0, 1.0, 0.0);
  cam.fov_y_deg = 60.0;
  cam.aspect = static_cast<double>(kW) / kH;
  cam.near = 0.05;
  cam.far = 1000.0;
  Basis b;
  if (!begin(cam, kW, kH, &b, error)) return false;
  const auto start = Clock::now();
  constexpr int kTiny = 20000;
  clear_instances();
  for (int i = 0; i < kTiny; ++i) instances.push_back(instance(b, Vec3(0.0, 0.0, -10.0), Vec3(0.02), true, 1));
  const std::size_t full = instances.size();
  instances.push_back(instance(b, Vec3(0.0, 0.0, -3.0), Vec3(10.0, 10.0, 1.0), true, 1));
  upload();
  depth_pass(b, kW, kH, 0);
  if (queries.size() < 256) {
    const std::size_t old = queries.size();
    queries.resize(256);
    glGenQueries(static_cast<GLsizei>(256 - old), queries.data() + old);
  }
  auto draw = [](std::size_t k, GLsizei count = 1) {
    glDrawElementsInstancedBaseInstance(GL_TRIANGLES, detail::kBoxIndices, GL_UNSIGNED_BYTE, nullptr, count, static_cast<GLuint>(k));
  };
  std::vector<GLuint> results;
  // As the levels read them: a round at once where the query buffer is on.
  auto read_all = [&](int count) { read_queries(static_cast<std::size_t>(count), &results); };
  constexpr int kCalls = 200, kFull = 16, kReps = 5;
  const double pixels = static_cast<double>(kW) * kH;
  CostModel c;
  c.device = device;

  // Drawing: depth test and writes on.
  const double calls_ms = median_ms(kReps, [&] {
    for (int i = 0; i < kCalls; ++i) draw(0);
  });
  c.render_setup_us = calls_ms * 1e3 / kCalls;
  const double many_ms = median_ms(kReps, [&] { draw(0, kTiny); });
  c.render_triangle_ns = std::max(0.0, many_ms - calls_ms / kCalls) * 1e6 / (12.0 * kTiny);
  const double full_ms = median_ms(kReps, [&] {
    for (int i = 0; i < kFull; ++i) draw(full);
  });
  c.render_fragment_ns = std::max(0.0, full_ms / kFull - calls_ms / kCalls) * 1e6 / pixels;
  const double plain_ms = calls_ms;
  const double with_ms = median_ms(kReps, [&] {
    for (int i = 0; i < kCalls; ++i) {
      glBeginQuery(GL_SAMPLES_PASSED, queries[static_cast<std::size_t>(i)]);
      draw(0);
      glEndQuery(GL_SAMPLES_PASSED);
    }
    read_all(kCalls);
  });
  c.query_overhead_us = std::max(0.0, with_ms - plain_ms) * 1e3 / kCalls;

  // Queries: depth test, no writes.
  begin_probes(0);
  const double q_ms = median_ms(kReps, [&] {
    for (int i = 0; i < kCalls; ++i) probe(GL_SAMPLES_PASSED, static_cast<std::size_t>(i), 0);
    read_all(kCalls);
  });
  c.query_setup_us = q_ms * 1e3 / kCalls;
  const double qfull_ms = median_ms(kReps, [&] {
    for (int i = 0; i < kFull; ++i) probe(GL_SAMPLES_PASSED, static_cast<std::size_t>(i), full);
    read_all(kFull);
  });
  c.query_fragment_ns = std::max(0.0, qfull_ms / kFull - q_ms / kCalls) * 1e6 / pixels;
  double latency = 0.0;
  for (int r = 0; r < 10; ++r) {
    glFinish();
    const auto t0 = Clock::now();
    probe(GL_SAMPLES_PASSED, 0, 0);
    read_all(1);
    latency = std::max(latency, ms_since(t0));
  }
  c.query_latency_us = latency * 1e3;
  end_probes();
  if (!gl_ok("measuring the cost model", error)) return false;
  c.calibration_ms = ms_since(start);
  refine.model = std::make_unique<CostModel>(c);

  char ms[32];
  std::snprintf(ms, sizeof ms, "%.0f", c.calibration_ms);
  *note = "cost model measured in ";
  *note += ms;
  *note += " ms";
  if (!unreadable.empty()) *note += " (" + unreadable + ")";
  if (path.empty()) {
    *note += "; not kept (no XDG_CACHE_HOME or HOME)";
    return true;
  }
  // Keep the other devices' models of the file.
  nlohmann::json out = {{"format", kFormat}, {"version", 1}, {"models", nlohmann::json::array()}};
  if (file.is_object() && file.value("format", "") == kFormat && file.contains("models") && file["models"].is_array())
    for (const nlohmann::json& e : file["models"])
      if (e.is_object() && e.value("device", "") != device) out["models"].push_back(e);
  out["models"].push_back(to_json(c));
  std::error_code ec;
  const std::filesystem::path p(path);
  if (std::filesystem::exists(p, ec) && !std::filesystem::is_regular_file(p, ec)) {
    // A device, a FIFO or a directory is never replaced by the file.
    *note += "; not saved: " + path + " is not a regular file";
    return true;
  }
  if (p.has_parent_path()) std::filesystem::create_directories(p.parent_path(), ec);
  const std::string tmp = path + ".tmp";
  {
    std::ofstream f(tmp, std::ios::trunc);
    f << out.dump(2) << '\n';
    f.close();
    if (!f) {
      *note += "; not saved: cannot write " + tmp + ": " + std::strerror(errno);
      std::filesystem::remove(tmp, ec);
      return true;
    }
  }
  std::filesystem::rename(tmp, p, ec);
  if (ec) {
    *note += "; not saved: " + ec.message();
    std::filesystem::remove(tmp, ec);
    return true;
  }
  *note += ", saved to " + path;
  return true;
}

bool Renderer::cost_model(const std::string& path, CostModel* out, std::string* note, std::string* error) {
  Impl& m = *impl_;
  if (!m.refine.model_path_set || m.refine.model_path != path) {
    m.refine.model.reset();
    m.refine.model_path = path;
    m.refine.model_path_set = true;
  }
  if (!m.egl->make_current(error)) return false;
  if (!m.ensure_model(note, error)) return false;
  *out = *m.refine.model;
  return true;
}

void Renderer::set_cost_model(const CostModel& model) {
  impl_->refine.model = std::make_unique<CostModel>(model);
  impl_->refine.model_path_set = true;
  impl_->refine.model_path.clear();
}

void Renderer::reset_refinement() {
  impl_->refine.ternary = {};
  impl_->refine.near_optimal = {};
}

}  // namespace voxvis::render
