// types.cpp — the out-of-line functions of voxvis/types.h.
#include "voxvis/types.h"

#include <charconv>
#include <cmath>
#include <string>

namespace voxvis {

std::string number_text(double v) {
  if (!std::isfinite(v)) return std::isnan(v) ? "nan" : (v > 0 ? "inf" : "-inf");
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}

}  // namespace voxvis
