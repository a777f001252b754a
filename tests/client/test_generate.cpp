// `voxvis generate` with the static scene presets (indoor, voxel-world,
// voxel-cave, city), run as a separate process: the files are the library's
// scenes and camera paths byte for byte, `voxvis replay` accepts them, the
// same arguments give the same bytes, and flags that do not apply or bad
// values are errors naming the flag. Small sizes and few frames.
#include <cstdint>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "cli_runner.h"
#include "files.h"
#include "voxvis/format.h"
#include "voxvis/generate.h"

namespace voxvis::test {
namespace {

using ::testing::HasSubstr;

/// 'text', as the messages quote values (built with += : GCC 12 warns
/// falsely, -Wrestrict, on "literal" + std::string).
std::string quoted(const char* text) {
  std::string out = "'";
  out += text;
  out += '\'';
  return out;
}

/// The text `voxvis generate` should write for a scene and camera path.
std::string scene_text(const ScenePath& p) { return scene_to_json(p.scene); }
std::string frames_text(const ScenePath& p) {
  std::string text;
  for (const FrameInput& f : camera_frames(p.cameras)) {
    text += frame_to_json(f);
    text += '\n';
  }
  return text;
}

class Generate : public Cli {
 protected:
  /// Runs `generate` into <tag>.json and <tag>.jsonl; returns the result.
  Result gen(const std::string& tag, std::vector<std::string> args) {
    args.insert(args.begin(), {"generate", "--scene-out", path(tag + ".json"), "--frames-out", path(tag + ".jsonl")});
    return run(args);
  }
  std::string scene(const std::string& tag) const { return slurp(path(tag + ".json")); }
  std::string frames(const std::string& tag) const { return slurp(path(tag + ".jsonl")); }

  /// A failure with exit status 2, a message naming `flag` and containing
  /// every one of `words`, and no files written.
  void expect_refused(const std::vector<std::string>& args, const std::string& flag,
                      const std::vector<std::string>& words) {
    SCOPED_TRACE(::testing::PrintToString(args));
    const Result r = gen("bad", args);
    EXPECT_EQ(r.signal, 0);
    EXPECT_EQ(r.status, 2) << r.err;
    EXPECT_THAT(r.err, HasSubstr("voxvis: error: " + flag + ": "));
    for (const std::string& w : words) {
      EXPECT_THAT(r.err, HasSubstr(w));
    }
    EXPECT_EQ(r.out, "");
    EXPECT_EQ(files(), std::vector<std::string>{});
  }
};

struct Case {
  std::string preset;
  std::string size;
  ScenePath expected;  ///< The library's scene at that size, 12 frames, seed 3.
};

std::vector<Case> small_cases() {
  return {{"indoor", "2x1", make_indoor_level(2, 1, 12, 3)},
          {"voxel-world", "16", make_voxel_world(16, 12, false, 3)},
          {"voxel-cave", "16", make_voxel_world(16, 12, true, 3)},
          {"city", "2", make_city(2, 12, 3)}};
}

TEST_F(Generate, PresetsWriteTheLibrarysScenesThatReplayAccepts) {
  for (const Case& c : small_cases()) {
    SCOPED_TRACE(c.preset);
    Result r = gen(c.preset, {"--preset", c.preset, "--size", c.size, "--frames", "12", "--seed", "3"});
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_EQ(r.out, "");
    // Byte for byte what the library builds: same objects, same cameras, as
    // FrameInput lines 1/60 s apart without moves.
    const std::string text = scene(c.preset);
    EXPECT_EQ(text, scene_text(c.expected));
    EXPECT_EQ(frames(c.preset), frames_text(c.expected));
    SceneDesc parsed;
    FormatError error;
    ASSERT_TRUE(parse_scene(text, c.preset, &parsed, &error)) << error.str();
    EXPECT_EQ(parsed.objects.size(), c.expected.scene.objects.size());
    EXPECT_GT(parsed.objects.size(), 10u);
    ASSERT_TRUE(parsed.grid.has_value());
    EXPECT_EQ(*parsed.grid, *c.expected.scene.grid);
    const std::vector<std::string> lines = lines_of(frames(c.preset));
    ASSERT_EQ(lines.size(), 12u);
    for (std::size_t i = 0; i < lines.size(); ++i) {
      const nlohmann::json j = nlohmann::json::parse(lines[i]);
      EXPECT_EQ(j.at("t").get<double>(), static_cast<double>(i) / 60.0);
      EXPECT_FALSE(j.contains("moves")) << lines[i];
    }

    r = run({"replay", "--scene", path(c.preset + ".json"), "--frames", path(c.preset + ".jsonl"), "-q"});
    ASSERT_EQ(r.status, 0) << r.err;
    const std::vector<std::string> out = lines_of(r.out);
    ASSERT_EQ(out.size(), 12u);
    std::size_t nonempty = 0;
    for (const std::string& l : out) {
      const nlohmann::json j = nlohmann::json::parse(l);
      EXPECT_EQ(j.at("stats").at("speed_violations").get<int>(), 0);
      if (!j.at("pvs").empty()) ++nonempty;
    }
    // The cameras look into their scenes (the city's last one looks past its edge).
    EXPECT_GE(nonempty, 9u);
  }
}

TEST_F(Generate, DefaultsAreTheBenchmarkScenes) {
  // tests/bench/bench_frame.cpp: indoor 6 x 3 rooms (seed 7), voxel world 64
  // (seed 11), city 8 x 8 (seed 5). The paths' length is --frames.
  const std::vector<Case> cases = {{"indoor", "", make_indoor_level(6, 3, 2, 7)},
                                   {"voxel-world", "", make_voxel_world(64, 2, false, 11)},
                                   {"voxel-cave", "", make_voxel_world(64, 2, true, 11)},
                                   {"city", "", make_city(8, 2, 5)}};
  for (const Case& c : cases) {
    SCOPED_TRACE(c.preset);
    const Result r = gen(c.preset, {"--preset", c.preset, "--frames", "2"});
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_EQ(scene(c.preset), scene_text(c.expected));
    EXPECT_EQ(frames(c.preset), frames_text(c.expected));
  }
  // The documented object counts.
  EXPECT_EQ(cases[0].expected.scene.objects.size(), 182u);
  EXPECT_EQ(cases[1].expected.scene.objects.size(), 30586u);
  EXPECT_EQ(cases[3].expected.scene.objects.size(), 495u);
  // The voxel world is the same with either path; the paths differ.
  EXPECT_EQ(scene("voxel-world"), scene("voxel-cave"));
  EXPECT_NE(frames("voxel-world"), frames("voxel-cave"));
  // --frames defaults to 300, as for paper.
  const Result r = gen("long", {"--preset", "city", "--size", "1"});
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(lines_of(frames("long")).size(), 300u);
}

TEST_F(Generate, PaperDefaultsAreUnchanged) {
  // No --objects, --dynamic or --seed: 5000 spheres, 200 moving, seed 1, the
  // walkthrough seed 2.
  const Result r = gen("paper", {"--frames", "3"});
  ASSERT_EQ(r.status, 0) << r.err;
  const SceneDesc desc = make_paper_scene(PaperSceneParams{});
  ASSERT_EQ(desc.objects.size(), 5000u);
  EXPECT_EQ(scene("paper"), scene_to_json(desc));
  WalkthroughParams w;
  w.frames = 3;
  std::string text;
  for (const FrameInput& f : make_walkthrough(desc, w)) {
    text += frame_to_json(f);
    text += '\n';
  }
  EXPECT_EQ(frames("paper"), text);
}

TEST_F(Generate, SameArgumentsSameBytesOtherSeedOtherScene) {
  for (const Case& c : small_cases()) {
    SCOPED_TRACE(c.preset);
    const std::vector<std::string> args = {"--preset", c.preset, "--size", c.size, "--frames", "5"};
    auto with_seed = [&](const std::string& seed) {
      std::vector<std::string> a = args;
      a.insert(a.end(), {"--seed", seed});
      return a;
    };
    ASSERT_EQ(gen("a", with_seed("21")).status, 0);
    ASSERT_EQ(gen("b", with_seed("21")).status, 0);
    ASSERT_EQ(gen("c", with_seed("22")).status, 0);
    EXPECT_FALSE(scene("a").empty());
    EXPECT_EQ(scene("a"), scene("b"));
    EXPECT_EQ(frames("a"), frames("b"));
    EXPECT_NE(scene("a"), scene("c"));
  }
  // Sizes: indoor N is N x N rooms; XxZ sets both.
  ASSERT_EQ(gen("n", {"--preset", "indoor", "--size", "3", "--frames", "1", "--seed", "4"}).status, 0);
  EXPECT_EQ(scene("n"), scene_text(make_indoor_level(3, 3, 1, 4)));
  ASSERT_EQ(gen("xz", {"--preset", "indoor", "--size", "1x4", "--frames", "1", "--seed", "4"}).status, 0);
  EXPECT_EQ(scene("xz"), scene_text(make_indoor_level(1, 4, 1, 4)));
  // The largest seed is accepted.
  ASSERT_EQ(gen("max", {"--preset", "city", "--size", "1", "--frames", "1", "--seed", "18446744073709551615"}).status, 0);
  EXPECT_EQ(scene("max"), scene_text(make_city(1, 1, 18446744073709551615ULL)));
}

TEST_F(Generate, FlagsThatDoNotApplyAreRefused) {
  expect_refused({"--preset", "city", "--objects", "10"}, "--objects", {"'paper' only", "'city'"});
  expect_refused({"--preset", "indoor", "--dynamic", "0"}, "--dynamic", {"'paper' and 'arena' only", "'indoor'"});
  expect_refused({"--preset", "arena", "--objects", "10"}, "--objects", {"'paper' only", "'arena'", "--dynamic"});
  expect_refused({"--preset", "voxel-cave", "--objects", "5000", "--dynamic", "200"}, "--objects",
                 {"'voxel-cave'"});
  expect_refused({"--preset", "paper", "--size", "8"}, "--size", {"'paper'"});
  expect_refused({"--size", "8"}, "--size", {"'paper'"});  // paper is the default preset
  expect_refused({"--preset", "castle"}, "--preset",
                 {"'castle'", "paper, indoor, voxel-world, voxel-cave, city, arena"});
}

TEST_F(Generate, BadValuesAreRefused) {
  // Zero, negative, not a number, over the cap (the message says the cap and why).
  expect_refused({"--preset", "city", "--size", "0"}, "--size", {"blocks per side", "'city'", "[1, 64]", "'0'"});
  expect_refused({"--preset", "city", "--size", "-2"}, "--size", {"[1, 64]", "'-2'"});
  expect_refused({"--preset", "city", "--size", "65"}, "--size", {"[1, 64]", "'65'", "million voxels"});
  expect_refused({"--preset", "city", "--size", "4x4"}, "--size", {"one number", "'4x4'"});
  expect_refused({"--preset", "voxel-world", "--size", "8"}, "--size", {"columns per side", "[16, 256]"});
  expect_refused({"--preset", "voxel-cave", "--size", "257"}, "--size", {"[16, 256]", "500,000 blocks"});
  expect_refused({"--preset", "voxel-world", "--size", "99999999999999999999999"}, "--size", {"[16, 256]"});
  expect_refused({"--preset", "indoor", "--size", "6x0"}, "--size", {"rooms per side", "[1, 100]", "'6x0'"});
  expect_refused({"--preset", "indoor", "--size", "101"}, "--size", {"[1, 100]", "100,000 objects"});
  expect_refused({"--preset", "arena", "--size", "1"}, "--size", {"rooms per side", "[2, 32]", "'1'"});
  expect_refused({"--preset", "arena", "--size", "33"}, "--size", {"[2, 32]", "million voxels"});
  expect_refused({"--preset", "arena", "--dynamic", "-1"}, "--dynamic", {"players", "[0, 1000]", "-1"});
  expect_refused({"--preset", "arena", "--dynamic", "1001"}, "--dynamic", {"[0, 1000]", "1001"});
  for (const char* bad : {"", "x", "6x", "x3", "6x3x2", "six", "4x-2", " 4", "4.5"}) {
    expect_refused({"--preset", "indoor", "--size", bad}, "--size",
                   {"N or XxZ", quoted(bad)});
  }
  expect_refused({"--preset", "city", "--frames", "-1"}, "--frames", {"[0, 100000]"});
  expect_refused({"--preset", "indoor", "--frames", "100001"}, "--frames", {"[0, 100000]"});
  expect_refused({"--frames", "100001"}, "--frames", {"[0, 100000]"});
  for (const char* bad : {"-1", "18446744073709551616", "0x10", "1e3", ""}) {
    expect_refused({"--preset", "city", "--seed", bad}, "--seed", {quoted(bad)});
  }
  expect_refused({"--seed", "-5"}, "--seed", {"'-5'"});
}

TEST_F(Generate, TheArenaIsTheLibrarysWithItsPlayersMoves) {
  // Byte for byte make_arena's scene and frames (every player moved each
  // frame); --dynamic sets the players; replay accepts it with no move too
  // fast. The default is 4 x 4 rooms, 24 players, seed 3.
  Result r = gen("arena", {"--preset", "arena", "--size", "2", "--frames", "12", "--seed", "9", "--dynamic", "6"});
  ASSERT_EQ(r.status, 0) << r.err;
  const ArenaLevel expected = make_arena(2, 6, 12, 9);
  EXPECT_EQ(scene("arena"), scene_to_json(expected.scene));
  std::string text;
  for (const FrameInput& f : expected.frames) {
    text += frame_to_json(f);
    text += '\n';
  }
  EXPECT_EQ(frames("arena"), text);
  const std::vector<std::string> lines = lines_of(frames("arena"));
  ASSERT_EQ(lines.size(), 12u);
  EXPECT_EQ(nlohmann::json::parse(lines[5]).at("moves").size(), 6u);
  r = run({"replay", "--scene", path("arena.json"), "--frames", path("arena.jsonl"), "-q"});
  ASSERT_EQ(r.status, 0) << r.err;
  for (const std::string& l : lines_of(r.out))
    EXPECT_EQ(nlohmann::json::parse(l).at("stats").at("speed_violations").get<int>(), 0) << l;
  r = gen("default", {"--preset", "arena", "--frames", "1"});
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(scene("default"), scene_to_json(make_arena(4, 24, 1, 3).scene));
}

TEST_F(Generate, HelpNamesThePresetsAndSizes) {
  const Result r = run({"generate", "--help"});
  EXPECT_EQ(r.status, 0);
  for (const char* word : {"--size", "indoor", "voxel-world", "voxel-cave", "city", "arena", "6x3"}) {
    EXPECT_THAT(r.out, HasSubstr(word));
  }
}

}  // namespace
}  // namespace voxvis::test
