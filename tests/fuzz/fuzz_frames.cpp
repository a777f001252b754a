// fuzz_frames.cpp — libFuzzer target of the frames parser: parse_frames, the
// whole-file path (line splitting, blank lines, line numbers) that `voxvis
// tick` and `voxvis loadgen` read files with, and through it
// parse_frame_line, which every other command calls line by line. An input
// is a frames file. Besides the sanitizers' checks:
//  * a refused file gets an error on one of its lines, in printable text;
//  * every frame read (before an error too) has the line it came from, and
//    survives a round trip: frame_to_json's line parses back to the same
//    frame, and writing that again gives the same text.
#include <cstddef>
#include <cstdint>
#include <sstream>
#include <string>
#include <string_view>
#include <vector>

#include "fuzz_check.h"
#include "voxvis/format.h"

namespace voxvis::fuzz {
namespace {

bool same_frame(const FrameInput& a, const FrameInput& b) {
  const Camera& x = a.camera;
  const Camera& y = b.camera;
  if (!same(a.t, b.t) || !same(x.eye, y.eye) || !same(x.dir, y.dir) || !same(x.up, y.up) ||
      !same(x.fov_y_deg, y.fov_y_deg) || !same(x.aspect, y.aspect) || !same(x.near, y.near) ||
      !same(x.far, y.far) || a.moves.size() != b.moves.size()) {
    return false;
  }
  for (std::size_t i = 0; i < a.moves.size(); ++i) {
    const Move& m = a.moves[i];
    const Move& n = b.moves[i];
    if (m.id != n.id || !same(m.center, n.center) || m.has_rotation != n.has_rotation) return false;
    if (m.has_rotation && !same(m.rotation, n.rotation)) return false;
  }
  return true;
}

void check_frame(const FrameInput& frame, int lines) {
  if (frame.line < 1 || frame.line > lines) {
    fail("a frame on line " + std::to_string(frame.line) + " of " + std::to_string(lines) + " lines");
  }
  const std::string written = frame_to_json(frame);
  FrameInput back;
  FormatError error;
  if (!parse_frame_line(written, "written.jsonl", frame.line, &back, &error)) {
    fail("the written frame does not parse: " + error.str() + "\n" + written);
  }
  if (back.line != frame.line) fail("the written frame's line is " + std::to_string(back.line));
  if (!same_frame(frame, back)) fail("the written frame parses to another frame:\n" + written);
  if (frame_to_json(back) != written) fail("writing the frame again gives another text:\n" + written);
}

}  // namespace
}  // namespace voxvis::fuzz

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace voxvis;
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  std::istringstream in{std::string(text)};
  std::vector<FrameInput> frames;
  FormatError error;
  const bool ok = parse_frames(in, "fuzz.jsonl", &frames, &error);
  if (!ok) fuzz::check_error(error, "fuzz.jsonl", text);
  const int lines = fuzz::line_count(text);
  int previous = 0;
  for (const FrameInput& frame : frames) {
    if (frame.line <= previous || (!ok && frame.line >= error.line)) {
      fuzz::fail("frame of line " + std::to_string(frame.line) + " out of order");
    }
    previous = frame.line;
    fuzz::check_frame(frame, lines);
  }
  return 0;
}
