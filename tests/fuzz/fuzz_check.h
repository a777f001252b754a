// fuzz_check.h — what the fuzz targets require of every input's outcome,
// beyond the sanitizers' checks. A broken rule aborts with a message, and
// libFuzzer keeps the input as a reproducer (crash-<sha1>).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <string_view>

#include "voxvis/format.h"

namespace voxvis::fuzz {

[[noreturn]] inline void fail(const std::string& what) {
  std::fprintf(stderr, "fuzz check failed: %s\n", what.c_str());
  std::abort();
}

/// The same double, sign of zero included (what a round trip must keep).
inline bool same(double a, double b) { return a == b && std::signbit(a) == std::signbit(b); }
inline bool same(const Vec3& a, const Vec3& b) { return same(a.x, b.x) && same(a.y, b.y) && same(a.z, b.z); }
inline bool same(const Quat& a, const Quat& b) {
  return same(a.w, b.w) && same(a.x, b.x) && same(a.y, b.y) && same(a.z, b.z);
}

/// Lines of `text` as an editor counts them: newlines + 1.
inline int line_count(std::string_view text) {
  return static_cast<int>(std::count(text.begin(), text.end(), '\n')) + 1;
}

/// Whether `s` is printable ASCII: an error goes on one terminal line, and
/// the input's own bytes (control characters, invalid UTF-8) are escaped.
inline bool printable(std::string_view s) {
  return std::all_of(s.begin(), s.end(), [](char c) { return c >= 0x20 && c < 0x7f; });
}

/// A refused input's error names the source, a line of the input and what
/// is wrong, in printable text.
inline void check_error(const FormatError& error, std::string_view source, std::string_view text) {
  const std::string where = "error \"" + error.str() + "\": ";
  if (error.message.empty()) fail(where + "no message");
  if (error.source != source) fail(where + "source is not \"" + std::string(source) + "\"");
  if (error.line < 1 || error.line > line_count(text)) {
    fail(where + "line " + std::to_string(error.line) + " is not a line of the input (1 to " +
         std::to_string(line_count(text)) + ")");
  }
  if (!printable(error.field)) fail(where + "field is not printable ASCII");
  if (!printable(error.message)) fail(where + "message is not printable ASCII");
}

}  // namespace voxvis::fuzz
