// types.cpp — the out-of-line functions of voxvis/types.h.
#include "voxvis/types.h"

#include <charconv>
#include <cmath>
#include <string>

namespace voxvis {

void append_number_text(std::string& out, double v) {
  if (!std::isfinite(v)) {
    out += std::isnan(v) ? "nan" : (v > 0 ? "inf" : "-inf");
    return;
  }
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  out.append(buf, r.ptr);
}

std::string number_text(double v) {
  std::string out;
  append_number_text(out, v);
  return out;
}

}  // namespace voxvis
