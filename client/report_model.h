// report_model.h — what `voxvis report` measures and prints, apart from the
// measuring: the configurations (a file, or the default sweep), the rows,
// which rows are Pareto-optimal, and the Markdown table.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

namespace voxvis::cli {

/// One configuration: the engine's options and a refinement level.
struct ReportConfig {
  std::string name;
  std::optional<glm::ivec3> grid;  ///< Empty: the scene's own (or automatic) grid.
  int occlusion_buffer = 160;      ///< 0: off.
  std::string level = "none";      ///< voxvis/refine.h's names.
};

/// Parses a configurations file: {"configs": [{"name": ..., "grid": [x, y, z],
/// "occlusion_buffer": W, "level": L}, ...]}. Every field but "name" is
/// optional. On error sets `message` naming the entry ("configs[2].level: ...").
bool parse_configs(const std::string& text, const std::string& path, std::vector<ReportConfig>* out,
                   std::string* message);

/// The default sweep around the scene's grid `g`: the buffer off and at 64,
/// 128, 160 (the engine's default), 256 and 512; the grid at half and twice
/// the resolution (buffer 128); and each refinement level with the buffer
/// at 128.
std::vector<ReportConfig> default_configs(const glm::ivec3& g);

/// A measured configuration.
struct ReportRow {
  std::string name;
  std::string error;  ///< Non-empty: the configuration could not run.
  std::size_t frames = 0;
  double median_ms = 0.0, p99_ms = 0.0;  ///< Engine plus refinement, per frame.
  double engine_ms = 0.0;                ///< Median of the engine alone.
  double tightness = 0.0;                ///< Total output size over total exactly visible.
  std::uint64_t misses = 0;              ///< Object-frames exactly visible but not in the output.
  /// Object-frames EGL showed only along an edge (its single precision) that
  /// the output lacks: not visible by the definition, not misses (verify's
  /// rule, reference.h: confirm_misses).
  std::uint64_t dismissed = 0;
  double queries = 0.0;                  ///< Per frame.
  /// The refinement level's costs, means per frame (render::RefineStats).
  double draw_calls = 0.0, pixels = 0.0, draw_ms = 0.0, query_ms = 0.0, wait_ms = 0.0;
  bool may_miss = false;                 ///< The level may drop visible objects (adaptive).
  bool pareto = false;
};

/// Marks the conservative rows (no miss) that no other conservative row
/// beats in both time (median) and tightness; rows with an error, a miss or
/// no tightness take no part. Ties: equal rows are both optimal.
void mark_pareto(std::vector<ReportRow>* rows);

/// The Markdown table, one row per configuration sorted by time, Pareto rows
/// marked with a star; failed configurations last, with their error.
std::string report_markdown(const std::vector<ReportRow>& rows, const std::string& reference);

}  // namespace voxvis::cli
