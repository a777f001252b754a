// report_model.cpp — see report_model.h.
#include "report_model.h"

#include <algorithm>
#include <cstdio>

#include <glm/common.hpp>
#include <nlohmann/json.hpp>

namespace voxvis::cli {

bool parse_configs(const std::string& text, const std::string& path, std::vector<ReportConfig>* out,
                   std::string* message) {
  const nlohmann::json j = nlohmann::json::parse(text, nullptr, false);
  if (j.is_discarded() || !j.is_object() || !j.contains("configs") || !j["configs"].is_array() ||
      j["configs"].empty()) {
    *message = path + ": expected {\"configs\": [ ... ]} with at least one configuration";
    return false;
  }
  out->clear();
  for (std::size_t i = 0; i < j["configs"].size(); ++i) {
    const nlohmann::json& c = j["configs"][i];
    const std::string at = path + ": configs[" + std::to_string(i) + "]";
    if (!c.is_object()) {
      *message = at + ": not an object";
      return false;
    }
    for (const auto& [key, value] : c.items()) {
      if (key != "name" && key != "grid" && key != "occlusion_buffer" && key != "level") {
        *message = at + "." + key + ": unknown field (known: name, grid, occlusion_buffer, level)";
        return false;
      }
    }
    ReportConfig rc;
    if (!c.contains("name") || !c["name"].is_string() || c["name"].get<std::string>().empty()) {
      *message = at + ".name: missing, or not a non-empty string";
      return false;
    }
    rc.name = c["name"].get<std::string>();
    for (const ReportConfig& prev : *out)
      if (prev.name == rc.name) {
        *message = at + ".name: '" + rc.name + "' is used twice";
        return false;
      }
    if (c.contains("grid")) {
      const nlohmann::json& g = c["grid"];
      if (!g.is_array() || g.size() != 3) {
        *message = at + ".grid: expected [NX, NY, NZ]";
        return false;
      }
      glm::ivec3 v;
      for (int a = 0; a < 3; ++a) {
        if (!g[static_cast<std::size_t>(a)].is_number_integer() || g[static_cast<std::size_t>(a)].get<long long>() < 1 ||
            g[static_cast<std::size_t>(a)].get<long long>() > 4096) {
          *message = at + ".grid: each resolution must be an integer from 1 to 4096";
          return false;
        }
        v[a] = g[static_cast<std::size_t>(a)].get<int>();
      }
      rc.grid = v;
    }
    if (c.contains("occlusion_buffer")) {
      const nlohmann::json& w = c["occlusion_buffer"];
      if (!w.is_number_integer() || (w.get<long long>() != 0 && (w.get<long long>() < 8 || w.get<long long>() > 4096))) {
        *message = at + ".occlusion_buffer: must be 0 (off) or a width from 8 to 4096 pixels";
        return false;
      }
      rc.occlusion_buffer = w.get<int>();
    }
    if (c.contains("level")) {
      if (!c["level"].is_string()) {
        *message = at + ".level: not a string";
        return false;
      }
      rc.level = c["level"].get<std::string>();
    }
    out->push_back(rc);
  }
  return true;
}

std::vector<ReportConfig> default_configs(const glm::ivec3& g) {
  std::vector<ReportConfig> v;
  for (int w : {0, 64, 128, 160, 256, 512})
    v.push_back(ReportConfig{w ? "buffer " + std::to_string(w) : "buffer off", std::nullopt, w, "none"});
  const glm::ivec3 half = glm::max(g / 2, glm::ivec3(1)), twice = glm::min(g * 2, glm::ivec3(4096));
  auto grid_name = [](const glm::ivec3& r) {
    return "grid " + std::to_string(r.x) + "x" + std::to_string(r.y) + "x" + std::to_string(r.z);
  };
  v.push_back(ReportConfig{grid_name(half) + ", buffer 128", half, 128, "none"});
  v.push_back(ReportConfig{grid_name(twice) + ", buffer 128", twice, 128, "none"});
  for (const char* level : {"queries", "hierarchical", "lazy-grid", "ternary", "near-optimal", "adaptive:4"})
    v.push_back(ReportConfig{std::string("buffer 128 + ") + level, std::nullopt, 128, level});
  return v;
}

void mark_pareto(std::vector<ReportRow>* rows) {
  for (ReportRow& r : *rows) {
    r.pareto = false;
    if (!r.error.empty() || r.misses > 0 || !(r.tightness == r.tightness)) continue;
    bool beaten = false;
    for (const ReportRow& o : *rows) {
      if (&o == &r || !o.error.empty() || o.misses > 0 || !(o.tightness == o.tightness)) continue;
      const bool no_worse = o.median_ms <= r.median_ms && o.tightness <= r.tightness;
      const bool better = o.median_ms < r.median_ms || o.tightness < r.tightness;
      if (no_worse && better) {
        beaten = true;
        break;
      }
    }
    r.pareto = !beaten;
  }
}

std::string report_markdown(const std::vector<ReportRow>& rows, const std::string& reference) {
  std::vector<const ReportRow*> ok, failed;
  for (const ReportRow& r : rows) (r.error.empty() ? ok : failed).push_back(&r);
  std::stable_sort(ok.begin(), ok.end(), [](const ReportRow* a, const ReportRow* b) { return a->median_ms < b->median_ms; });
  std::string s = "| configuration | median ms | p99 ms | engine ms | tightness | misses | queries/frame | Pareto |\n"
                  "|---|---|---|---|---|---|---|---|\n";
  char buf[256];
  for (const ReportRow* r : ok) {
    std::snprintf(buf, sizeof buf, "| %s | %.2f | %.2f | %.2f | %.3f | %llu%s | %.0f | %s |\n", r->name.c_str(),
                  r->median_ms, r->p99_ms, r->engine_ms, r->tightness, static_cast<unsigned long long>(r->misses),
                  r->may_miss ? " (may miss)" : "", r->queries, r->pareto ? "*" : "");
    s += buf;
  }
  for (const ReportRow* r : failed) s += "| " + r->name + " | could not run: " + r->error + " | | | | | | |\n";
  std::uint64_t dismissed = 0;
  for (const ReportRow& r : rows) dismissed += r.dismissed;
  s += "\nTightness and misses against the exactly visible set at " + reference +
       "; time per frame is the engine's plus the refinement's; * marks the Pareto-optimal rows among those "
       "with no miss (no other such row is both faster and tighter). \"frustum culling only\" is every object's "
       "box against the frustum on the same frames: the baseline an occlusion culler has to beat.";
  if (dismissed > 0)
    s += " A sighting EGL made only along an edge (its single precision), which the ray caster does not confirm, "
         "is not visible by the definition and is not counted as a miss, as `voxvis verify` counts it: " +
         std::to_string(dismissed) + " such object-frames were dismissed over all rows.";
  return s + "\n";
}

}  // namespace voxvis::cli
