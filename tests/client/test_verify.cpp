// `voxvis verify` on this machine's EGL (llvmpipe in CI): the engine's PVS
// misses nothing on generated scenes, a PVS cut on purpose is caught to the
// object, slices of a job concatenate to the whole, bad input is an error.
// Few frames at low resolutions: each frame costs milliseconds on llvmpipe.
#include <algorithm>
#include <cstdint>
#include <set>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "cli_runner.h"
#include "files.h"
#include "scenes.h"
#include "voxvis/format.h"
#include "voxvis/generate.h"

namespace voxvis::test {
namespace {

using ::testing::HasSubstr;

std::vector<std::uint64_t> ids_of(const nlohmann::json& a) {
  std::vector<std::uint64_t> v;
  for (const auto& x : a) v.push_back(x.get<std::uint64_t>());
  return v;
}

class Verify : public Cli {
 protected:
  /// Writes a scene and its camera path as frames (60 per second).
  void write(const ScenePath& sp, const std::string& scene, const std::string& frames) {
    spit(path(scene), scene_to_json(sp.scene));
    std::string text;
    for (std::size_t i = 0; i < sp.cameras.size(); ++i) {
      FrameInput f;
      f.t = static_cast<double>(i) / 60.0;
      f.camera = sp.cameras[i];
      text += frame_to_json(f) + "\n";
    }
    spit(path(frames), text);
  }
  /// paper.json and paper.jsonl: 600 spheres, 60 of them moving.
  void write_paper(int frames) { Cli::write_paper("paper.json", "paper.jsonl", 600, 60, frames); }
  /// The parsed output lines; checks their shape.
  std::vector<nlohmann::json> lines(const std::string& out) {
    std::vector<nlohmann::json> v;
    for (const std::string& l : lines_of(out)) {
      nlohmann::json j = nlohmann::json::parse(l, nullptr, false);
      EXPECT_FALSE(j.is_discarded()) << l;
      if (j.is_discarded()) continue;
      for (const char* key : {"frame", "visible", "missed", "pvs_size", "stats"}) EXPECT_TRUE(j.contains(key)) << l;
      v.push_back(std::move(j));
    }
    return v;
  }
};

TEST_F(Verify, TheEnginesPvsMissesNothingOnGeneratedScenes) {
  struct Case {
    std::string name;
    ScenePath sp;
  };
  std::vector<Case> cases;
  cases.push_back({"indoor", make_indoor_level(2, 2, 8, 3)});
  cases.push_back({"cave", make_voxel_world(24, 8, true, 4)});
  cases.push_back({"surface", make_voxel_world(24, 8, false, 4)});
  cases.push_back({"city", make_city(2, 8, 5)});
  for (const Case& c : cases) {
    write(c.sp, c.name + ".json", c.name + ".jsonl");
    const Result r = run({"verify", "--scene", path(c.name + ".json"), "--frames", path(c.name + ".jsonl"),
                          "--resolution", "160x90"});
    ASSERT_EQ(r.status, 0) << c.name << "\n" << r.err;
    const auto out = lines(r.out);
    ASSERT_EQ(out.size(), c.sp.cameras.size()) << c.name;
    std::size_t seen = 0;
    for (std::size_t i = 0; i < out.size(); ++i) {
      EXPECT_EQ(out[i]["frame"].get<std::size_t>(), i);
      EXPECT_TRUE(out[i]["missed"].empty()) << c.name << ": " << out[i].dump();
      seen += out[i]["visible"].size();
      EXPECT_LE(out[i]["visible"].size(), out[i]["pvs_size"].get<std::size_t>());
    }
    EXPECT_GT(seen, out.size()) << c.name << ": hardly anything visible";
    EXPECT_THAT(r.err, HasSubstr("0 missed object-frames"));
    EXPECT_THAT(r.err, HasSubstr("tightness"));
  }
  // Moving objects, and the other method.
  write_paper(10);
  for (const std::vector<std::string>& extra :
       {std::vector<std::string>{}, std::vector<std::string>{"--method", "queries", "--full"}}) {
    std::vector<std::string> args = {"verify", "--scene", path("paper.json"), "--frames", path("paper.jsonl"),
                                     "--resolution", "128x72", "-q"};
    args.insert(args.end(), extra.begin(), extra.end());
    const Result r = run(args);
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_EQ(r.err, "");
    const auto out = lines(r.out);
    ASSERT_EQ(out.size(), 10u);
    for (const auto& j : out) EXPECT_TRUE(j["missed"].empty()) << j.dump();
  }
}

TEST_F(Verify, FindsExactlyTheMissesOfACutPvs) {
  write_paper(12);
  Result r = run({"replay", "--scene", path("paper.json"), "--frames", path("paper.jsonl"), "--out",
                  path("pvs.jsonl"), "-q"});
  ASSERT_EQ(r.status, 0) << r.err;
  r = run({"verify", "--scene", path("paper.json"), "--frames", path("paper.jsonl"), "--pvs", path("pvs.jsonl"),
           "--resolution", "128x72", "-q"});
  ASSERT_EQ(r.status, 0) << r.err;
  const auto whole = lines(r.out);
  ASSERT_EQ(whole.size(), 12u);

  // Cut from every third frame its first two visible objects.
  std::string cut;
  std::vector<std::vector<std::uint64_t>> removed(whole.size());
  const std::vector<std::string> pvs_lines = lines_of(slurp(path("pvs.jsonl")));
  ASSERT_EQ(pvs_lines.size(), whole.size());
  for (std::size_t i = 0; i < pvs_lines.size(); ++i) {
    nlohmann::json j = nlohmann::json::parse(pvs_lines[i]);
    const auto vis = ids_of(whole[i]["visible"]);
    if (i % 3 == 0)
      for (std::size_t k = 0; k < std::min<std::size_t>(2, vis.size()); ++k) removed[i].push_back(vis[k]);
    nlohmann::json kept = nlohmann::json::array();
    for (const auto& id : j["pvs"])
      if (std::find(removed[i].begin(), removed[i].end(), id.get<std::uint64_t>()) == removed[i].end())
        kept.push_back(id);
    j["pvs"] = kept;
    cut += j.dump() + "\n";
  }
  spit(path("cut.jsonl"), cut);
  r = run({"verify", "--scene", path("paper.json"), "--frames", path("paper.jsonl"), "--pvs", path("cut.jsonl"),
           "--resolution", "128x72"});
  EXPECT_EQ(r.status, 3) << r.err;
  const auto out = lines(r.out);
  ASSERT_EQ(out.size(), whole.size());
  std::size_t frames_cut = 0;
  for (std::size_t i = 0; i < out.size(); ++i) {
    EXPECT_EQ(ids_of(out[i]["missed"]), removed[i]) << "frame " << i;
    EXPECT_EQ(out[i]["visible"], whole[i]["visible"]) << "frame " << i;
    if (!removed[i].empty()) {
      ++frames_cut;
      EXPECT_THAT(r.err, HasSubstr("MISS: frame " + std::to_string(i) + " "));
    }
  }
  EXPECT_GE(frames_cut, 3u);
}

TEST_F(Verify, SlicesConcatenateToTheWholeJob) {
  write_paper(9);
  auto strip = [](std::vector<nlohmann::json> v) {
    for (auto& j : v) j.erase("stats");  // Times differ run to run.
    return v;
  };
  Result r = run({"verify", "--scene", path("paper.json"), "--frames", path("paper.jsonl"), "--resolution",
                  "96x54", "-q"});
  ASSERT_EQ(r.status, 0) << r.err;
  const auto whole = strip(lines(r.out));
  ASSERT_EQ(whole.size(), 9u);
  std::vector<nlohmann::json> joined;
  for (const auto& [first, count] : std::vector<std::pair<int, int>>{{0, 4}, {4, 3}, {7, -1}}) {
    r = run({"verify", "--scene", path("paper.json"), "--frames", path("paper.jsonl"), "--resolution", "96x54",
             "-q", "--first-frame", std::to_string(first), "--frame-count", std::to_string(count)});
    ASSERT_EQ(r.status, 0) << r.err;
    for (auto& j : strip(lines(r.out))) joined.push_back(j);
  }
  EXPECT_EQ(joined, whole);
}

TEST_F(Verify, BadInputIsAClearError) {
  write_paper(4);
  const std::vector<std::string> base = {"verify", "--scene", path("paper.json"), "--frames", path("paper.jsonl")};
  auto with = [&](std::vector<std::string> extra) {
    std::vector<std::string> a = base;
    a.insert(a.end(), extra.begin(), extra.end());
    return a;
  };
  struct Case {
    std::vector<std::string> args;
    std::string message;
  };
  const std::string too_wide = "100000x16";
  spit(path("short.jsonl"), lines_of(slurp(path("paper.jsonl")))[0] + "\n");
  Result r = run({"replay", "--scene", path("paper.json"), "--frames", path("paper.jsonl"), "--out",
                  path("pvs.jsonl"), "-q"});
  ASSERT_EQ(r.status, 0) << r.err;
  const std::vector<std::string> pvs = lines_of(slurp(path("pvs.jsonl")));
  spit(path("few.jsonl"), pvs[0] + "\n" + pvs[1] + "\n");
  spit(path("many.jsonl"), slurp(path("pvs.jsonl")) + pvs[3] + "\n");
  spit(path("stranger.jsonl"), pvs[0] + "\n{\"frame\": 1, \"pvs\": [3, 99999]}\n");
  spit(path("order.jsonl"), pvs[1] + "\n");
  // Moves of objects the scene lacks or holds static, with a PVS file (no
  // engine to refuse them).
  nlohmann::json moved = nlohmann::json::parse(lines_of(slurp(path("paper.jsonl")))[0]);
  moved["moves"] = nlohmann::json::parse(R"([{"id": 987654, "center": [1, 2, 3]}])");
  spit(path("unknown_move.jsonl"), moved.dump() + "\n");
  moved["moves"] = nlohmann::json::parse(R"([{"id": 500, "center": [1, 2, 3]}])");  // Ids above 60 are static.
  spit(path("static_move.jsonl"), moved.dump() + "\n");
  spit(path("one_pvs.jsonl"), pvs[0] + "\n");
  const std::vector<Case> cases = {
      {{"verify", "--scene", path("paper.json"), "--frames", path("unknown_move.jsonl"), "--pvs",
        path("one_pvs.jsonl")},
       "unknown_move.jsonl:1: moves[0].id: unknown object id 987654"},
      {{"verify", "--scene", path("paper.json"), "--frames", path("static_move.jsonl"), "--pvs",
        path("one_pvs.jsonl")},
       "static_move.jsonl:1: moves[0].id: object 500 is static and cannot move"},
      {with({"--resolution", "0x10"}), "--resolution: width and height must be >= 1"},
      {with({"--resolution", "640"}), "--resolution: expected WIDTHxHEIGHT"},
      {with({"--resolution", "-5x10"}), "--resolution: expected WIDTHxHEIGHT"},
      {with({"--resolution", too_wide}), "--resolution: " + too_wide + " exceeds this OpenGL's limit"},
      {with({"--method", "magic"}), "--method: unknown method 'magic'"},
      {with({"--egl-platform", "x11"}), "--egl-platform: unknown EGL platform 'x11'"},
      {with({"--egl-device", "7", "--egl-platform", "device"}), "--egl-device 7 does not exist"},
      {with({"--first-frame", "9"}), "--first-frame: is 9, the file has 4 frames"},
      {with({"--frame-count", "10"}), "--frame-count: asked for frames 0 to 9, the file has 4"},
      {with({"--pvs", path("few.jsonl")}), "few.jsonl: has no line for frame 2"},
      {with({"--pvs", path("many.jsonl")}), "many.jsonl:5: more PVS lines than frames"},
      {with({"--pvs", path("stranger.jsonl")}), "stranger.jsonl:2: pvs: id 99999 is not an object of the scene"},
      {with({"--pvs", path("order.jsonl")}), "order.jsonl:1: frame: expected 0"},
      {with({"--pvs", path("absent.jsonl")}), "absent.jsonl: cannot open"},
  };
  for (const Case& c : cases) {
    r = run(c.args);
    EXPECT_EQ(r.status, 2) << c.message << "\n" << r.err;
    EXPECT_EQ(r.signal, 0);
    EXPECT_THAT(r.err, HasSubstr("voxvis: error: ")) << c.message;
    EXPECT_THAT(r.err, HasSubstr(c.message)) << r.err;
  }
  // No EGL on the machine: glvnd finds no vendor library.
  r = run(base, {"__EGL_VENDOR_LIBRARY_FILENAMES=/nonexistent/voxvis-no-egl.json"});
  EXPECT_EQ(r.status, 2) << r.err;
  EXPECT_EQ(r.signal, 0);
  EXPECT_THAT(r.err, HasSubstr("voxvis: error: EGL: no EGL implementation found"));
  EXPECT_EQ(r.out, "");
}

}  // namespace
}  // namespace voxvis::test
