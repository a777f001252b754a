// numeric.h — small numeric helpers shared by the engine's sources.
#pragma once

#include <algorithm>
#include <cmath>
#include <string>

#include "voxvis/types.h"

namespace voxvis::detail {

inline bool finite3(const Vec3& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

/// Largest absolute component.
inline double max_abs(const Vec3& v) {
  return std::max(std::fabs(v.x), std::max(std::fabs(v.y), std::fabs(v.z)));
}

}  // namespace voxvis::detail
