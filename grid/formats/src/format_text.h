// format_text.h — the number and vector text both the readers (format.cpp)
// and the writers (format_write.cpp) of the batch formats produce.
#pragma once

#include <charconv>
#include <cmath>
#include <string>

#include "voxvis/types.h"

namespace voxvis::detail {

template <typename Int>
inline void append_int(std::string& out, Int v) {
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  out.append(buf, r.ptr);
}

/// JSON number text that parses back to exactly `v`: number_text's
/// (shortest round-trip form) with JSON's two exceptions. Null for
/// non-finite values, which no voxvis format accepts; negative zero is
/// "-0.0", since "-0" reads back as the integer 0, whose double is +0.
inline void append_number(std::string& out, double v) {
  if (!std::isfinite(v)) {
    out += "null";
    return;
  }
  if (v == 0.0 && std::signbit(v)) {
    out += "-0.0";
    return;
  }
  append_number_text(out, v);
}

inline void append_vec3(std::string& out, const Vec3& v) {
  out += '[';
  append_number(out, v.x);
  out += ", ";
  append_number(out, v.y);
  out += ", ";
  append_number(out, v.z);
  out += ']';
}

}  // namespace voxvis::detail
