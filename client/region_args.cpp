// region_args.cpp — the region flags of replay, view, tick and loadgen
// (cli.h, RegionArgs).
#include <cstdlib>
#include <string>
#include <vector>

#include "cli.h"
#include "voxvis/scene.h"

namespace voxvis::cli {
namespace {

/// "H" (all three) or "HX,HY,HZ": numbers strtod reads whole.
bool parse_extent(const std::string& text, Vec3* out) {
  std::vector<double> v;
  std::size_t at = 0;
  while (at <= text.size()) {
    const std::size_t comma = std::min(text.find(',', at), text.size());
    const std::string part = text.substr(at, comma - at);
    char* end = nullptr;
    const double d = std::strtod(part.c_str(), &end);
    if (part.empty() || end != part.c_str() + part.size()) return false;
    v.push_back(d);
    at = comma + 1;
  }
  if (v.size() == 1) *out = Vec3(v[0]);
  else if (v.size() == 3) *out = Vec3(v[0], v[1], v[2]);
  else return false;
  return true;
}

}  // namespace

void RegionOverride::apply(Camera* camera) const {
  if (extent_set) camera->eye_extent = extent;
  if (omnidirectional) camera->omnidirectional = true;
  if (horizon_set) camera->horizon_s = horizon;
}

bool parse_region_args(const RegionArgs& args, RegionOverride* out, FormatError* error) {
  RegionOverride r;
  if (!args.eye_extent.empty()) {
    if (!parse_extent(args.eye_extent, &r.extent)) {
      *error = FormatError{"", 0, "--eye-extent", "expected H or HX,HY,HZ (world units), got '" + args.eye_extent + "'"};
      return false;
    }
    r.extent_set = true;
  }
  r.omnidirectional = args.omnidirectional;
  if (args.horizon) {
    r.horizon = *args.horizon;
    r.horizon_set = true;
  }
  // The engine's rules, on a camera that is otherwise fine.
  Camera probe;
  r.apply(&probe);
  if (const Status st = validate_camera(probe); !st.ok) {
    *error = FormatError{"", 0, st.field == "horizon_s" ? "--horizon" : "--eye-extent", st.message};
    return false;
  }
  *out = r;
  return true;
}

}  // namespace voxvis::cli
