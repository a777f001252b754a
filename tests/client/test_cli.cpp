// Tests of the `voxvis` command line, run as a separate process (VOXVIS_CLI)
// on temporary files: exit statuses, messages, output files.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "cli_runner.h"
#include "files.h"
#include <nlohmann/json.hpp>

namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using ::testing::Not;
using voxvis::test::Cli;
using voxvis::test::Result;
using voxvis::test::lines_of;
using voxvis::test::slurp;
using voxvis::test::spit;

// A small valid scene: a static wall (id 1) and a dynamic sphere (id 2).
constexpr const char* kScene = R"({
  "format": "voxvis-scene/1",
  "bounds": {"min": [0, 0, 0], "max": [20, 20, 20]},
  "grid": [16, 16, 16],
  "objects": [
    {"id": 1, "shape": "box", "min": [4, 0, 9], "max": [16, 20, 10]},
    {"id": 2, "shape": "sphere", "center": [10, 10, 15], "radius": 1, "dynamic": true, "max_speed": 5},
    {"id": 3, "shape": "sphere", "center": [10, 10, 5], "radius": 1}
  ]
}
)";

/// A frames line at time t; `extra` is inserted before the closing brace.
std::string frame(double t, const std::string& extra = "",
                  const std::string& up = "[0, 1, 0]", const std::string& fov = "60",
                  const std::string& near = "0.05", const std::string& far = "100") {
  std::ostringstream s;
  s << "{\"t\": " << t << ", \"eye\": [10, 10, 1], \"dir\": [0, 0, 1], \"up\": " << up
    << ", \"fov_y_deg\": " << fov << ", \"aspect\": 1.5, \"near\": " << near
    << ", \"far\": " << far << extra << "}";
  return s.str();
}

void expect_clean_failure(const Result& r, const std::string& where, const std::string& what = "") {
  EXPECT_EQ(r.signal, 0) << "killed by signal " << r.signal << "\n" << r.err;
  EXPECT_EQ(r.status, 2) << r.err;
  EXPECT_THAT(r.err, HasSubstr("voxvis: error: " + where)) << r.err;
  if (!what.empty()) {
    EXPECT_THAT(r.err, HasSubstr(what)) << r.err;
  }
  EXPECT_EQ(r.out, "");
}

/// Checks one output line and returns it parsed.
nlohmann::json check_output_line(const std::string& line, std::size_t index) {
  const nlohmann::json j = nlohmann::json::parse(line, nullptr, false);
  EXPECT_FALSE(j.is_discarded()) << line;
  if (j.is_discarded()) return j;
  EXPECT_EQ(j.at("frame").get<std::size_t>(), index);
  for (const char* key : {"pvs", "wake"}) {
    const auto& ids = j.at(key);
    EXPECT_TRUE(ids.is_array());
    for (std::size_t i = 1; i < ids.size(); ++i) {
      EXPECT_LT(ids[i - 1].get<std::uint64_t>(), ids[i].get<std::uint64_t>()) << key << ": " << line;
    }
  }
  const auto& s = j.at("stats");
  for (const char* key : {"voxels_visited", "shells", "objects_discretized", "tbvs_created",
                          "tbvs_revealed", "tbvs_expired", "tbvs_active", "speed_violations",
                          "outside_tested", "pvs_size", "front_voxels_culled", "front_objects_culled"}) {
    EXPECT_TRUE(s.at(key).is_number_unsigned() || s.at(key).get<std::int64_t>() >= 0) << key;
  }
  EXPECT_GE(s.at("time_us").get<double>(), 0.0);
  // Its split: each part within the whole (the clock read around it).
  for (const char* part : {"traverse_us", "render_us", "retest_us"}) {
    EXPECT_GE(s.at(part).get<double>(), 0.0) << part;
    EXPECT_LE(s.at(part).get<double>(), s.at("time_us").get<double>() + 0.001) << part;
  }
  EXPECT_LE(s.at("render_us").get<double>(), s.at("traverse_us").get<double>() + 0.001);
  EXPECT_TRUE(s.at("early_exit").is_boolean());
  EXPECT_EQ(s.at("pvs_size").get<std::size_t>(), j.at("pvs").size());
  return j;
}

// ---------------------------------------------------------------------------

TEST_F(Cli, VersionAndHelp) {
  Result r = run({"--version"});
  EXPECT_EQ(r.status, 0);
  EXPECT_THAT(r.out, HasSubstr("voxvis 0."));

  r = run({"--help"});
  EXPECT_EQ(r.status, 0);
  EXPECT_THAT(r.out, HasSubstr("replay"));
  EXPECT_THAT(r.out, HasSubstr("generate"));

  r = run({"replay", "--help"});
  EXPECT_EQ(r.status, 0);
  for (const char* opt : {"--scene", "--frames", "--grid", "--out", "--tbv-period", "--quiet"}) {
    EXPECT_THAT(r.out, HasSubstr(opt));
  }
  r = run({"generate", "--help"});
  EXPECT_EQ(r.status, 0);
  for (const char* opt : {"--preset", "--scene-out", "--frames-out", "--objects", "--dynamic",
                          "--frames", "--seed"}) {
    EXPECT_THAT(r.out, HasSubstr(opt));
  }
}

TEST_F(Cli, UsageErrorsExitTwo) {
  for (const std::vector<std::string>& args :
       {std::vector<std::string>{}, {"frobnicate"}, {"replay"}, {"replay", "--scene", "x.json"},
        {"generate", "--scene-out", "a.json"}, {"replay", "--bogus"}}) {
    const Result r = run(args);
    EXPECT_EQ(r.signal, 0);
    EXPECT_EQ(r.status, 2) << r.err;
    EXPECT_THAT(r.err, HasSubstr("voxvis: error: "));
  }
}

TEST_F(Cli, GenerateThenReplay) {
  const std::string scene = path("scene.json"), frames = path("frames.jsonl"),
                    out = path("pvs.jsonl");
  Result r = run({"generate", "--preset", "paper", "--scene-out", scene, "--frames-out", frames,
               "--objects", "400", "--dynamic", "25", "--frames", "40", "--seed", "5"});
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(lines_of(slurp(frames)).size(), 40u);
  EXPECT_THAT(slurp(scene), HasSubstr("\"format\": \"voxvis-scene/1\""));

  r = run({"replay", "--scene", scene, "--frames", frames, "--out", out, "--quiet"});
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(r.out, "");
  EXPECT_EQ(r.err, "");  // --quiet
  const std::vector<std::string> lines = lines_of(slurp(out));
  ASSERT_EQ(lines.size(), 40u);
  std::size_t nonempty = 0;
  for (std::size_t i = 0; i < lines.size(); ++i) {
    const nlohmann::json j = check_output_line(lines[i], i);
    if (!j.is_discarded() && !j.at("pvs").empty()) ++nonempty;
  }
  EXPECT_GT(nonempty, 0u);
  EXPECT_EQ(files(), (std::vector<std::string>{"frames.jsonl", "pvs.jsonl", "scene.json"}));

  // To stdout, with a summary on stderr; same PVS lines (the stats' times differ).
  r = run({"replay", "--scene", scene, "--frames", frames, "--grid", "20,12,20"});
  ASSERT_EQ(r.status, 0) << r.err;
  const std::vector<std::string> lines2 = lines_of(r.out);
  ASSERT_EQ(lines2.size(), 40u);
  for (std::size_t i = 0; i < lines2.size(); ++i) check_output_line(lines2[i], i);
  EXPECT_THAT(r.err, HasSubstr("40 frames"));
  EXPECT_THAT(r.err, HasSubstr("median"));
  EXPECT_THAT(r.err, HasSubstr("p99"));

  // A fixed TBV period is accepted.
  r = run({"replay", "--scene", scene, "--frames", frames, "--tbv-period", "0.25", "-q"});
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(lines_of(r.out).size(), 40u);
}

TEST_F(Cli, GenerateIsDeterministic) {
  const auto gen = [&](const std::string& tag, const std::string& seed) {
    const Result r = run({"generate", "--scene-out", path(tag + ".json"), "--frames-out",
                       path(tag + ".jsonl"), "--objects", "200", "--dynamic", "10", "--frames",
                       "10", "--seed", seed});
    EXPECT_EQ(r.status, 0) << r.err;
    return slurp(path(tag + ".json")) + slurp(path(tag + ".jsonl"));
  };
  const std::string a = gen("a", "7");
  EXPECT_FALSE(a.empty());
  EXPECT_EQ(a, gen("b", "7"));
  EXPECT_NE(a, gen("c", "8"));
}

TEST_F(Cli, GenerateRejectsBadCounts) {
  const std::string s = path("s.json"), f = path("f.jsonl");
  expect_clean_failure(
      run({"generate", "--scene-out", s, "--frames-out", f, "--objects", "5", "--dynamic", "6"}),
      "--dynamic");
  expect_clean_failure(run({"generate", "--scene-out", s, "--frames-out", f, "--objects", "-1"}),
                       "--objects");
  const Result r = run({"generate", "--preset", "cathedral", "--scene-out", s, "--frames-out", f});
  EXPECT_EQ(r.status, 2);
  EXPECT_THAT(r.err, HasSubstr("cathedral"));
  EXPECT_EQ(files(), std::vector<std::string>{});
}

TEST_F(Cli, BlankLinesAreSkippedButCounted) {
  spit(path("scene.json"), kScene);
  spit(path("frames.jsonl"), std::string("\n") + frame(0) + "\n   \n\n" + frame(0.1) + "\n\n");
  Result r = run({"replay", "--scene", path("scene.json"), "--frames", path("frames.jsonl"), "-q"});
  ASSERT_EQ(r.status, 0) << r.err;
  const std::vector<std::string> lines = lines_of(r.out);
  ASSERT_EQ(lines.size(), 2u);
  check_output_line(lines[0], 0);
  check_output_line(lines[1], 1);

  // Line numbers in messages count the blank lines too.
  spit(path("frames.jsonl"), std::string("\n") + frame(0) + "\n\n{\"t\": oops}\n");
  r = run({"replay", "--scene", path("scene.json"), "--frames", path("frames.jsonl"), "--out",
           path("pvs.jsonl"), "-q"});
  expect_clean_failure(r, path("frames.jsonl") + ":4: ", "malformed JSON");
  EXPECT_FALSE(fs::exists(path("pvs.jsonl")));
}

TEST_F(Cli, FailedRunLeavesNoPartialOutput) {
  spit(path("scene.json"), kScene);
  spit(path("frames.jsonl"), frame(0) + "\n" + frame(0.1) + "\n" + frame(0.2, "", "[0, 0, 1]") + "\n");
  spit(path("pvs.jsonl"), "previous results\n");
  const Result r = run({"replay", "--scene", path("scene.json"), "--frames", path("frames.jsonl"),
                     "--out", path("pvs.jsonl")});
  expect_clean_failure(r, path("frames.jsonl") + ":3: up: ", "parallel");
  EXPECT_EQ(slurp(path("pvs.jsonl")), "previous results\n");
  EXPECT_EQ(files(), (std::vector<std::string>{"frames.jsonl", "pvs.jsonl", "scene.json"}));
}

TEST_F(Cli, MissingFiles) {
  spit(path("scene.json"), kScene);
  spit(path("frames.jsonl"), frame(0) + "\n");
  expect_clean_failure(run({"replay", "--scene", path("nope.json"), "--frames", path("frames.jsonl")}),
                       path("nope.json") + ": cannot open");
  expect_clean_failure(run({"replay", "--scene", path("scene.json"), "--frames", path("nope.jsonl")}),
                       path("nope.jsonl") + ": cannot open");
  expect_clean_failure(run({"replay", "--scene", path("scene.json"), "--frames",
                            path("frames.jsonl"), "--out", path("no/such/dir/pvs.jsonl")}),
                       path("no/such/dir/pvs.jsonl") + ": cannot create");
}

// ---------------------------------------------------------------------------
// Bad scenes: "<file>:<line>: <field>: <message>" on stderr, exit 2.

struct BadScene {
  const char* name;
  std::string scene;
  std::string where;  // Expected after the scene path: ":line: field".
  std::string what;
};

void PrintTo(const BadScene& c, std::ostream* os) { *os << c.name; }

class CliBadScene : public Cli, public ::testing::WithParamInterface<BadScene> {};

TEST_P(CliBadScene, FailsCleanly) {
  const BadScene& c = GetParam();
  spit(path("scene.json"), c.scene);
  spit(path("frames.jsonl"), frame(0) + "\n");
  const Result r = run({"replay", "--scene", path("scene.json"), "--frames", path("frames.jsonl"),
                     "--out", path("pvs.jsonl")});
  expect_clean_failure(r, path("scene.json") + c.where, c.what);
  EXPECT_FALSE(fs::exists(path("pvs.jsonl")));
  EXPECT_EQ(files(), (std::vector<std::string>{"frames.jsonl", "scene.json"}));
}

std::string scene_with(const std::string& from, const std::string& to) {
  std::string s = kScene;
  const std::size_t at = s.find(from);
  if (at == std::string::npos) {
    ADD_FAILURE() << "no '" << from << "' in the test scene";
  } else {
    s.replace(at, from.size(), to);
  }
  return s;
}

INSTANTIATE_TEST_SUITE_P(
    All, CliBadScene,
    ::testing::Values(
        BadScene{"Malformed", scene_with("\"grid\": [16, 16, 16],", "\"grid\": [16, 16, 16]"), ":5: ",
                 "malformed JSON"},
        BadScene{"UnknownShape", scene_with("\"shape\": \"box\"", "\"shape\": \"cone\""),
                 ":6: objects[0].shape: ", "unknown shape \"cone\""},
        BadScene{"DuplicateId", scene_with("{\"id\": 3,", "{\"id\": 2,"), ":8: objects[2].id: ",
                 "duplicate id 2, first at line 7"},
        BadScene{"Overflow", scene_with("\"radius\": 1, \"dynamic\"", "\"radius\": 1e999, \"dynamic\""),
                 ":7: objects[1].radius: ", "out of range"},
        BadScene{"NegativeRadius", scene_with("\"radius\": 1}", "\"radius\": -1}"),
                 ":8: objects[2].radius: ", "must be > 0, got -1"},
        BadScene{"BoxMinAboveMax", scene_with("\"max\": [16, 20, 10]", "\"max\": [16, 20, 8]"),
                 ":6: objects[0].max: ", "max.z = 8 < min.z = 9"},
        BadScene{"ZeroGrid", scene_with("[16, 16, 16]", "[16, 0, 16]"), ":4: grid[1]: ",
                 "must be an integer >= 1"},
        BadScene{"UnknownKey", scene_with("\"radius\": 1}", "\"radius\": 1, \"mass\": 3}"),
                 ":8: objects[2]: ", "unknown key 'mass'"},
        // Refused by the engine, before allocating, on the line of the field.
        BadScene{"TooManyVoxels", scene_with("[16, 16, 16]", "[8192, 8192, 8]"), ":4: grid: ",
                 "exceeds the limit"},
        BadScene{"WrongFormat", scene_with("voxvis-scene/1", "voxvis-scene/9"), ":2: format: ",
                 "unsupported format"}),
    [](const auto& param_info) { return std::string(param_info.param.name); });

// ---------------------------------------------------------------------------
// Bad --grid values.

TEST_F(Cli, BadGridArguments) {
  spit(path("scene.json"), kScene);
  spit(path("frames.jsonl"), frame(0) + "\n");
  const auto replay = [&](const std::string& grid) {
    return run({"replay", "--scene", path("scene.json"), "--frames", path("frames.jsonl"), "--out",
                path("pvs.jsonl"), "--grid", grid});
  };
  expect_clean_failure(replay("0,10,10"), "--grid: ", "must be >= 1");
  expect_clean_failure(replay("-4,10,10"), "--grid: ", "must be >= 1");
  expect_clean_failure(replay("10,10"), "--grid: ", "NX,NY,NZ");
  expect_clean_failure(replay("10,10,10,10"), "--grid: ", "NX,NY,NZ");
  expect_clean_failure(replay("a,b,c"), "--grid: ", "NX,NY,NZ");
  expect_clean_failure(replay("10, 10, 10"), "--grid: ", "NX,NY,NZ");
  expect_clean_failure(replay("1.5,10,10"), "--grid: ", "NX,NY,NZ");
  expect_clean_failure(replay("99999999999999999999999,1,1"), "--grid: ", "exceeds");

  // Absurd resolutions fail fast, before anything is allocated.
  Result r = replay("100000,100000,100000");
  expect_clean_failure(r, "--grid: ", "exceeds the limit of 8192");
  EXPECT_LT(r.seconds, 5.0);
  // Within the per-axis limit but far too many voxels: refused by the engine.
  r = replay("8192,8192,8192");
  expect_clean_failure(r, path("scene.json") + ": grid: ", "exceeds");
  EXPECT_LT(r.seconds, 5.0);
  EXPECT_EQ(files(), (std::vector<std::string>{"frames.jsonl", "scene.json"}));

  // A valid override works.
  r = replay("4,5,6");
  EXPECT_EQ(r.status, 0) << r.err;
}

TEST_F(Cli, BadTbvPeriod) {
  spit(path("scene.json"), kScene);
  spit(path("frames.jsonl"), frame(0) + "\n");
  for (const char* v : {"-1", "nan", "inf"}) {
    const Result r = run({"replay", "--scene", path("scene.json"), "--frames", path("frames.jsonl"),
                       "--tbv-period", v});
    EXPECT_EQ(r.signal, 0);
    EXPECT_EQ(r.status, 2) << v << ": " << r.err;
    EXPECT_THAT(r.err, HasSubstr("--tbv-period")) << v;
  }
}

// ---------------------------------------------------------------------------
// Bad frames: the error names the frames file, the line and the field.

struct BadFrames {
  const char* name;
  std::string second_line;  // Line 1 is a valid frame at t = 1.
  std::string where;        // Expected after the frames path.
  std::string what;
};

void PrintTo(const BadFrames& c, std::ostream* os) { *os << c.name; }

class CliBadFrames : public Cli, public ::testing::WithParamInterface<BadFrames> {};

TEST_P(CliBadFrames, FailsCleanly) {
  const BadFrames& c = GetParam();
  spit(path("scene.json"), kScene);
  spit(path("frames.jsonl"), frame(1, ", \"moves\": [{\"id\": 2, \"center\": [10, 10, 15]}]") +
                                 "\n" + c.second_line + "\n" + frame(5) + "\n");
  const Result r = run({"replay", "--scene", path("scene.json"), "--frames", path("frames.jsonl"),
                     "--out", path("pvs.jsonl")});
  expect_clean_failure(r, path("frames.jsonl") + c.where, c.what);
  EXPECT_EQ(files(), (std::vector<std::string>{"frames.jsonl", "scene.json"}));
}

INSTANTIATE_TEST_SUITE_P(
    All, CliBadFrames,
    ::testing::Values(
        BadFrames{"UpParallelToDir", frame(2, "", "[0, 0, -3]"), ":2: up: ", "parallel"},
        BadFrames{"Fov180", frame(2, "", "[0, 1, 0]", "180"), ":2: fov_y_deg: ", ""},
        BadFrames{"NearEqualsFar", frame(2, "", "[0, 1, 0]", "60", "10", "10"), ":2: far: ", ""},
        BadFrames{"NearAboveFar", frame(2, "", "[0, 1, 0]", "60", "20", "10"), ":2: far: ", ""},
        BadFrames{"NegativeNear", frame(2, "", "[0, 1, 0]", "60", "-1"), ":2: near: ", ""},
        BadFrames{"Overflow", frame(2, "", "[0, 1e999, 0]"), ":2: up[1]: ", "out of range"},
        BadFrames{"MissingKey", "{\"t\": 2}", ":2: ", "missing required key 'eye'"},
        BadFrames{"UnknownKey", frame(2, ", \"speed\": 1"), ":2: ", "unknown key 'speed'"},
        BadFrames{"Malformed", frame(2).substr(0, 20), ":2: ", "malformed JSON"},
        BadFrames{"MoveUnknownId", frame(2, ", \"moves\": [{\"id\": 99, \"center\": [1, 1, 1]}]"),
                  ":2: moves[0].id: ", "99"},
        BadFrames{"MoveStaticId",
                  frame(2, ", \"moves\": [{\"id\": 2, \"center\": [10, 10, 15]}, "
                           "{\"id\": 1, \"center\": [1, 1, 1]}]"),
                  ":2: moves[1].id: ", "static"},
        BadFrames{"MoveDuplicateId",
                  frame(2, ", \"moves\": [{\"id\": 2, \"center\": [10, 10, 15]}, "
                           "{\"id\": 2, \"center\": [10, 10, 14]}]"),
                  ":2: moves[1].id: ", "duplicate id 2"},
        BadFrames{"MoveBadCenter", frame(2, ", \"moves\": [{\"id\": 2, \"center\": [10, 10]}]"),
                  ":2: moves[0].center: ", "3 numbers"},
        BadFrames{"TimeBackwards", frame(0.5), ":2: t: ", "backwards"},
        BadFrames{"TimeBeyondRange", frame(1e14), ":2: t: ", "within [-1e+10, 1e+10], got 1e+14"},
        BadFrames{"TimeInMicroseconds", frame(1.7e15), ":2: t: ", "microseconds"},
        BadFrames{"TimeHugeNegative", frame(-1e300), ":2: t: ", "within"},
        BadFrames{"TimeBackwardsWithMoves",
                  frame(0.5, ", \"moves\": [{\"id\": 2, \"center\": [10, 10, 15]}]"), ":2: t: ",
                  "backwards"}),
    [](const auto& param_info) { return std::string(param_info.param.name); });

TEST_F(Cli, TooFastMovesAreCountedNotRefused) {
  spit(path("scene.json"), kScene);
  // Object 2 has max_speed 5: moving 8 units in 1 s is too fast.
  spit(path("frames.jsonl"),
       frame(0, ", \"moves\": [{\"id\": 2, \"center\": [10, 10, 15]}]") + "\n" +
           frame(1, ", \"moves\": [{\"id\": 2, \"center\": [2, 10, 15]}]") + "\n");
  const Result r = run({"replay", "--scene", path("scene.json"), "--frames", path("frames.jsonl")});
  ASSERT_EQ(r.status, 0) << r.err;
  const std::vector<std::string> lines = lines_of(r.out);
  ASSERT_EQ(lines.size(), 2u);
  const nlohmann::json j = check_output_line(lines[1], 1);
  EXPECT_EQ(j.at("stats").at("speed_violations"), 1);
  EXPECT_THAT(r.err, HasSubstr("too-fast moves 1"));
}

TEST_F(Cli, ExamplesReplay) {
  const fs::path scene = fs::path(VOXVIS_SOURCE_DIR) / "examples/paper/scene.json";
  const fs::path frames = fs::path(VOXVIS_SOURCE_DIR) / "examples/paper/frames.jsonl";
  if (!fs::exists(scene) || !fs::exists(frames)) GTEST_SKIP() << "no examples/paper files";
  const Result r = run({"replay", "--scene", scene.string(), "--frames", frames.string(), "--out",
                     path("pvs.jsonl"), "-q"});
  ASSERT_EQ(r.status, 0) << r.err;
  const std::vector<std::string> lines = lines_of(slurp(path("pvs.jsonl")));
  EXPECT_EQ(lines.size(), lines_of(slurp(frames)).size());
  for (std::size_t i = 0; i < lines.size(); ++i) check_output_line(lines[i], i);
}

}  // namespace
