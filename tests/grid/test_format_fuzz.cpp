// test_format_fuzz.cpp — mutation tests of the parsers of untrusted input.
//
// Valid scene documents and frame lines are mutated at random (bytes flipped,
// inserted, deleted, spans duplicated, truncated, digits replaced by extreme
// numbers) and fed to the parsers, and whatever parses is fed on to the
// engine. Every input must end in either success or an error that names what
// is wrong: never a crash, a hang or an empty message. Under the sanitizer
// build this also checks memory safety. Deterministic: seeds are fixed.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <string>
#include <vector>

#include "scenes.h"
#include "voxvis/format.h"
#include "voxvis/scene.h"

namespace voxvis {
namespace {

constexpr const char* kScene = R"({
  "format": "voxvis-scene/1",
  "bounds": {"min": [0, 0, 0], "max": [20, 12, 20]},
  "grid": [10, 6, 10],
  "objects": [
    {"id": 7, "shape": "sphere", "center": [10, 6, 10], "radius": 1.5},
    {"id": 8, "shape": "box", "min": [1, 2, 3], "max": [5, 4, 6], "dynamic": true, "max_speed": 2.5},
    {"id": 9, "shape": "sphere", "center": [-5, 7, 25], "radius": 0.25, "dynamic": true, "max_speed": 1}
  ]
}
)";

constexpr const char* kFrame =
    R"({"t": 0.5, "eye": [10, 6, 30], "dir": [0, 0, -1], "up": [0, 1, 0], "fov_y_deg": 60, )"
    R"("aspect": 1.5, "near": 0.05, "far": 100, "moves": [{"id": 8, "center": [3, 3, 4.5]}]})";

int lines(const std::string& text) {
  return static_cast<int>(std::count(text.begin(), text.end(), '\n'));
}

/// Uniform in [0, n), n >= 1.
std::size_t below(test::Rng& rng, std::size_t n) { return static_cast<std::size_t>(rng.bits() % n); }

/// One random edit of `text`.
std::string mutate(const std::string& text, test::Rng& rng) {
  static const char* const kTokens[] = {"1e999", "-1e999", "NaN", "-0", "1e308", "4294967296",
                                        "-1",    "0",      "[",   "]",  "{",     "}",
                                        ",",     ":",      "\"",  "null", "true", "1e-320",
                                        "\xff",  "\\u0000", "[[[[[[[[", "0.5"};
  std::string s = text;
  const int edits = 1 + static_cast<int>(below(rng, 4));
  for (int e = 0; e < edits; ++e) {
    const std::size_t at = s.empty() ? 0 : static_cast<std::size_t>(below(rng, s.size()));
    switch (below(rng, 6)) {
      case 0:  // Change a digit (keeps many documents valid) or flip a byte.
        if (s.empty()) break;
        if (s[at] >= '0' && s[at] <= '9') {
          s[at] = static_cast<char>('0' + below(rng, 10));
        } else {
          s[at] = static_cast<char>(below(rng, 256));
        }
        break;
      case 1:  // Delete a span.
        s.erase(at, static_cast<std::size_t>(below(rng, 8) + 1));
        break;
      case 2: {  // Insert a token.
        const auto& tok = kTokens[below(rng, sizeof kTokens / sizeof kTokens[0])];
        s.insert(at, tok);
        break;
      }
      case 3: {  // Duplicate a span elsewhere.
        const std::size_t len = static_cast<std::size_t>(below(rng, 24) + 1);
        const std::string span = s.substr(at, len);
        s.insert(s.empty() ? 0 : static_cast<std::size_t>(below(rng, s.size())), span);
        break;
      }
      case 4:  // Truncate.
        s.resize(at);
        break;
      default: {  // Replace a digit with an extreme number.
        const std::size_t d = s.find_first_of("0123456789", at);
        if (d != std::string::npos) s.replace(d, 1, kTokens[below(rng, 8)]);
        break;
      }
    }
  }
  return s;
}

TEST(FormatFuzz, MutatedScenesParseOrFailWithAMessage) {
  test::Rng rng(0xf022);
  const int rounds = test::scaled(20000);
  int accepted = 0;
  for (int i = 0; i < rounds; ++i) {
    const std::string text = mutate(kScene, rng);
    SceneDesc desc;
    FormatError err;
    if (!parse_scene(text, "fuzz.json", &desc, &err)) {
      ASSERT_FALSE(err.message.empty()) << "round " << i << ":\n" << text;
      EXPECT_LE(err.line, lines(text) + 1) << "round " << i;
      continue;
    }
    ++accepted;
    // Whatever parses goes on to the engine, which may still refuse it.
    std::unique_ptr<Scene> scene;
    const Status st = Scene::create(desc, SceneOptions{}, &scene);
    if (!st.ok) {
      EXPECT_FALSE(st.message.empty()) << "round " << i;
      EXPECT_LE(scene_field_line(text, st.field), lines(text) + 1) << "round " << i;
      continue;
    }
    Scratch scratch;
    FrameResult result;
    Camera cam;
    cam.eye = Vec3(10, 6, 30);
    ASSERT_TRUE(scene->frame(scene->add_viewer(), cam, 0.0, scratch, &result).ok) << "round " << i;
  }
  // The mutations must leave some documents valid, or the engine half of
  // this test would test nothing.
  EXPECT_GT(accepted, rounds / 100);
}

TEST(FormatFuzz, MutatedFrameLinesParseOrFailWithAMessage) {
  SceneDesc desc;
  FormatError err;
  ASSERT_TRUE(parse_scene(kScene, "scene.json", &desc, &err)) << err.str();
  std::unique_ptr<Scene> scene;
  ASSERT_TRUE(Scene::create(desc, SceneOptions{}, &scene).ok);
  Scratch scratch;
  const ViewerId viewer = scene->add_viewer();
  test::Rng rng(0xf023);
  const int rounds = test::scaled(20000);
  int accepted = 0;
  double t = 0.0;
  for (int i = 0; i < rounds; ++i) {
    const std::string line = mutate(kFrame, rng);
    FrameInput frame;
    if (!parse_frame_line(line, "fuzz.jsonl", i + 1, &frame, &err)) {
      ASSERT_FALSE(err.message.empty()) << "round " << i << ": " << line;
      EXPECT_EQ(err.line, i + 1);
      continue;
    }
    ++accepted;
    // Time is made to go forward so that the engine sees the rest of it.
    t += 0.01;
    Status st = scene->apply_moves(t, frame.moves);
    if (!st.ok) {
      EXPECT_FALSE(st.message.empty());
      continue;
    }
    FrameResult result;
    st = scene->frame(viewer, frame.camera, t, scratch, &result);
    if (!st.ok) {
      EXPECT_FALSE(st.message.empty());
    }
  }
  EXPECT_GT(accepted, rounds / 100);
}

}  // namespace
}  // namespace voxvis
