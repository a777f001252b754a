// Region cameras in the command line: replay's --eye-extent, --omnidirectional
// and --horizon equal the frames file's fields; verify checks region frames
// by the ray caster's sampling and finds the misses of a cut PVS; bad flag
// values are errors naming the flag.
#include <algorithm>
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

class RegionCli : public Cli {
 protected:
  void SetUp() override {
    Cli::SetUp();
    const ArenaLevel a = make_arena(2, 6, 12, 4);
    spit(path("arena.json"), scene_to_json(a.scene));
    std::string plain, fields;
    for (FrameInput f : a.frames) {
      plain += frame_to_json(f) + "\n";
      f.camera.eye_extent = Vec3(20.0, 6.0, 20.0);
      f.camera.omnidirectional = true;
      f.camera.horizon_s = 0.05;
      fields += frame_to_json(f) + "\n";
    }
    spit(path("plain.jsonl"), plain);
    spit(path("fields.jsonl"), fields);
  }
  Result replay(const std::string& frames, std::vector<std::string> extra, const std::string& out) {
    std::vector<std::string> args = {"replay", "--scene", path("arena.json"), "--frames", path(frames), "--out",
                                     path(out), "-q"};
    args.insert(args.end(), extra.begin(), extra.end());
    return run(args);
  }
};

/// The PVS of each output line.
std::vector<nlohmann::json> pvs_of(const std::string& text) {
  std::vector<nlohmann::json> out;
  for (const std::string& l : lines_of(text)) out.push_back(nlohmann::json::parse(l).at("pvs"));
  return out;
}

TEST_F(RegionCli, FlagsEqualTheFramesFilesFields) {
  Result r = replay("plain.jsonl", {"--eye-extent", "20,6,20", "--omnidirectional", "--horizon", "0.05"}, "a.jsonl");
  ASSERT_EQ(r.status, 0) << r.err;
  r = replay("fields.jsonl", {}, "b.jsonl");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(pvs_of(slurp(path("a.jsonl"))), pvs_of(slurp(path("b.jsonl"))));
  EXPECT_THAT(slurp(path("a.jsonl")), HasSubstr("\"region\":true"));
  // The point answers are smaller, and carry no "region".
  r = replay("plain.jsonl", {}, "point.jsonl");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_THAT(slurp(path("point.jsonl")), ::testing::Not(HasSubstr("region")));
  std::size_t point = 0, region = 0;
  for (const auto& p : pvs_of(slurp(path("point.jsonl")))) point += p.size();
  for (const auto& p : pvs_of(slurp(path("a.jsonl")))) region += p.size();
  EXPECT_GT(region, point);
  // One number sets all three half extents.
  r = replay("plain.jsonl", {"--eye-extent", "20", "--omnidirectional", "--horizon", "0.05"}, "c.jsonl");
  ASSERT_EQ(r.status, 0) << r.err;
  r = replay("plain.jsonl", {"--eye-extent", "20,20,20", "--omnidirectional", "--horizon", "0.05"}, "d.jsonl");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(pvs_of(slurp(path("c.jsonl"))), pvs_of(slurp(path("d.jsonl"))));
}

TEST_F(RegionCli, VerifyChecksRegionFramesAndFindsACutPvsMisses) {
  Result r = replay("fields.jsonl", {}, "pvs.jsonl");
  ASSERT_EQ(r.status, 0) << r.err;
  r = run({"verify", "--scene", path("arena.json"), "--frames", path("fields.jsonl"), "--pvs", path("pvs.jsonl"),
           "--resolution", "48x27", "--region-eyes", "4"});
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_THAT(r.err, HasSubstr("region frames are checked by the CPU ray caster's sampling"));
  EXPECT_THAT(r.err, HasSubstr("six faces each"));
  EXPECT_THAT(r.err, HasSubstr("0 missed object-frames"));
  std::size_t seen = 0;
  std::vector<ObjectId> visible_somewhere;
  for (const std::string& l : lines_of(r.out)) {
    const nlohmann::json j = nlohmann::json::parse(l);
    seen += j.at("visible").size();
    for (const auto& id : j.at("visible")) visible_somewhere.push_back(id.get<ObjectId>());
  }
  ASSERT_GT(seen, 12u) << "the region sees hardly anything";
  // Cut one object the region sees out of every line: verify names it.
  const ObjectId cut = visible_somewhere.front();
  std::string cut_text;
  for (const std::string& l : lines_of(slurp(path("pvs.jsonl")))) {
    nlohmann::json j = nlohmann::json::parse(l);
    nlohmann::json kept = nlohmann::json::array();
    for (const auto& id : j.at("pvs"))
      if (id.get<ObjectId>() != cut) kept.push_back(id);
    j["pvs"] = kept;
    cut_text += j.dump() + "\n";
  }
  spit(path("cut.jsonl"), cut_text);
  r = run({"verify", "--scene", path("arena.json"), "--frames", path("fields.jsonl"), "--pvs", path("cut.jsonl"),
           "--resolution", "48x27", "--region-eyes", "4"});
  EXPECT_EQ(r.status, 3) << r.err;
  EXPECT_THAT(r.err, HasSubstr("MISS"));
  EXPECT_THAT(r.out, HasSubstr("\"missed\":[" + std::to_string(cut) + "]"));
}

TEST_F(RegionCli, HorizonFramesCheckEachAnswerWhereTheObjectsWent) {
  // The engine's region answers hold against the objects of the frames
  // within each one's horizon (50 ms: the next 3 frames at 60 per second).
  Result r = replay("fields.jsonl", {}, "pvs.jsonl");
  ASSERT_EQ(r.status, 0) << r.err;
  const std::vector<std::string> base = {"verify", "--scene", path("arena.json"), "--frames", path("fields.jsonl"),
                                         "--resolution", "48x27", "--region-eyes", "2"};
  auto verify = [&](const std::string& pvs, std::vector<std::string> extra) {
    std::vector<std::string> args = base;
    args.insert(args.end(), {"--pvs", path(pvs)});
    args.insert(args.end(), extra.begin(), extra.end());
    return run(args);
  };
  const Result own = verify("pvs.jsonl", {});
  ASSERT_EQ(own.status, 0) << own.err;
  const Result later = verify("pvs.jsonl", {"--horizon-frames", "3"});
  ASSERT_EQ(later.status, 0) << later.err;
  EXPECT_THAT(later.err, HasSubstr("with the objects of the next 3 frames within its horizon"));
  // One line a frame, in order; each frame's visible set is its own and
  // more (the later frames' sightings).
  const std::vector<std::string> a = lines_of(own.out), b = lines_of(later.out);
  ASSERT_EQ(a.size(), b.size());
  std::size_t grown = 0;
  std::string own_sets;
  for (std::size_t i = 0; i < a.size(); ++i) {
    const nlohmann::json ja = nlohmann::json::parse(a[i]), jb = nlohmann::json::parse(b[i]);
    EXPECT_EQ(jb.at("frame").get<std::size_t>(), i);
    const auto va = ja.at("visible").get<std::vector<ObjectId>>(), vb = jb.at("visible").get<std::vector<ObjectId>>();
    EXPECT_TRUE(std::includes(vb.begin(), vb.end(), va.begin(), va.end())) << "frame " << i;
    grown += vb.size() > va.size() ? 1 : 0;
    own_sets += nlohmann::json{{"frame", i}, {"pvs", va}}.dump() + "\n";
  }
  EXPECT_GT(grown, 0u) << "the later frames never saw more";
  // A PVS of exactly what each frame's own check sees passes it, and
  // misses what the later frames see.
  spit(path("own.jsonl"), own_sets);
  EXPECT_EQ(verify("own.jsonl", {}).status, 0);
  r = verify("own.jsonl", {"--horizon-frames", "3"});
  EXPECT_EQ(r.status, 3) << r.err;
  EXPECT_THAT(r.err, HasSubstr("MISS"));
  // The last frames have fewer after them: still one line each.
  EXPECT_EQ(lines_of(r.out).size(), a.size());
  r = verify("pvs.jsonl", {"--horizon-frames", "1001"});
  EXPECT_EQ(r.status, 2);
  EXPECT_THAT(r.err, HasSubstr("--horizon-frames: must be in [0, 1000], got 1001"));
}

TEST_F(RegionCli, BadFlagsAreErrorsNamingThem) {
  struct Case {
    std::vector<std::string> args;
    std::string expected;
  };
  for (const Case& c : std::vector<Case>{{{"--eye-extent", "-1"}, "--eye-extent: half extents must be >= 0"},
                                         {{"--eye-extent", "1,2"}, "--eye-extent: expected H or HX,HY,HZ"},
                                         {{"--eye-extent", "1,x,2"}, "--eye-extent: expected H or HX,HY,HZ"},
                                         {{"--eye-extent", "nan"}, "--eye-extent: must be three finite numbers"},
                                         {{"--eye-extent", "2e12"}, "--eye-extent: half extent exceeds"},
                                         {{"--horizon", "-0.5"}, "--horizon: must be in [0,"},
                                         {{"--horizon", "1e10"}, "--horizon: must be in [0,"}}) {
    SCOPED_TRACE(c.expected);
    const Result r = replay("plain.jsonl", c.args, "bad.jsonl");
    EXPECT_EQ(r.status, 2);
    EXPECT_THAT(r.err, HasSubstr("voxvis: error: " + c.expected));
    const Result v = run({"verify", "--scene", path("arena.json"), "--frames", path("plain.jsonl"), c.args[0],
                          c.args[1]});
    EXPECT_EQ(v.status, 2);
    EXPECT_THAT(v.err, HasSubstr(c.expected));
  }
  const Result r = run({"verify", "--scene", path("arena.json"), "--frames", path("plain.jsonl"), "--region-eyes",
                        "-3"});
  EXPECT_EQ(r.status, 2);
  EXPECT_THAT(r.err, HasSubstr("--region-eyes: must be in [0, 1000]"));
}

}  // namespace
}  // namespace voxvis::test
