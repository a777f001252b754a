// `voxvis verify-merge`: the slices of a verification split over workers
// (the indexed Job of deploy/k8s/verify-job.yaml) join into the whole run's
// lines, in frame order whatever the order given; a lost slice, a gap, an
// overlap or a line that is not verify's is named; a miss in any slice makes
// the exit status 3.
#include <filesystem>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "cli_runner.h"

namespace voxvis::test {
namespace {

using ::testing::HasSubstr;

/// Each line without its timings (stats), which differ between runs.
std::vector<std::string> without_stats(const std::string& text) {
  std::vector<std::string> out;
  for (const std::string& line : lines_of(text)) {
    nlohmann::json j = nlohmann::json::parse(line);
    j.erase("stats");
    out.push_back(j.dump());
  }
  return out;
}

TEST_F(Cli, VerifyMergeJoinsSlicesIntoTheWholeRun) {
  write_paper("scene.json", "frames.jsonl", 300, 20, 12);
  const std::vector<std::string> common = {"--scene", path("scene.json"), "--frames", path("frames.jsonl"),
                                           "--reference", "raycast", "--resolution", "64x36", "-q"};
  const auto verify = [&](std::vector<std::string> extra) {
    std::vector<std::string> args = {"verify"};
    args.insert(args.end(), common.begin(), common.end());
    args.insert(args.end(), extra.begin(), extra.end());
    const Result r = run(args);
    EXPECT_EQ(r.status, 0) << r.err;
  };
  verify({"--out", path("whole.jsonl")});
  verify({"--first-frame", "0", "--frame-count", "5", "--out", path("s0.jsonl")});
  verify({"--first-frame", "5", "--frame-count", "5", "--out", path("s1.jsonl")});
  verify({"--first-frame", "10", "--frame-count", "2", "--out", path("s2.jsonl")});

  Result r = run({"verify-merge", path("s2.jsonl"), path("s0.jsonl"), path("s1.jsonl"), "--frames", "12", "--out",
                  path("merged.jsonl")});
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_THAT(r.err, HasSubstr("3 slices, 12 frames: 0 missed object-frames"));
  EXPECT_EQ(without_stats(slurp(path("merged.jsonl"))), without_stats(slurp(path("whole.jsonl"))));

  // A lost slice: the middle (a gap) or the last (--frames).
  r = run({"verify-merge", path("s0.jsonl"), path("s2.jsonl"), "--out", path("gap.jsonl")});
  EXPECT_EQ(r.status, 2);
  EXPECT_THAT(r.err, HasSubstr("s2.jsonl: frames 5 to 9 are in no slice"));
  r = run({"verify-merge", path("s0.jsonl"), path("s1.jsonl"), "--frames", "12"});
  EXPECT_EQ(r.status, 2);
  EXPECT_THAT(r.err, HasSubstr("--frames: the slices cover frames 0 to 9 of 12"));
  r = run({"verify-merge", path("s1.jsonl"), path("s2.jsonl"), "--frames", "12"});
  EXPECT_EQ(r.status, 2);
  EXPECT_THAT(r.err, HasSubstr("no slice has frames 0 to 4"));
  // An overlap: the same slice twice.
  r = run({"verify-merge", path("s0.jsonl"), path("s0.jsonl")});
  EXPECT_EQ(r.status, 2);
  EXPECT_THAT(r.err, HasSubstr("frame 0 is in two slices"));
  EXPECT_FALSE(std::filesystem::exists(path("gap.jsonl")));

  // Nothing to merge, and a negative count.
  spit(path("empty.jsonl"), "");
  r = run({"verify-merge", path("empty.jsonl")});
  EXPECT_EQ(r.status, 2);
  EXPECT_THAT(r.err, HasSubstr("no frame in any slice (1 files): nothing to merge"));
  r = run({"verify-merge", path("s0.jsonl"), "--frames", "-5"});
  EXPECT_EQ(r.status, 2);
  EXPECT_THAT(r.err, HasSubstr("--frames"));

  // Not verify's output.
  spit(path("bad.jsonl"), "{\"frame\":0,\"pvs\":[1,2]}\n");
  r = run({"verify-merge", path("bad.jsonl")});
  EXPECT_EQ(r.status, 2);
  EXPECT_THAT(r.err, HasSubstr("bad.jsonl:1: not a `voxvis verify` output line"));

  // A slice with a miss: exit 3, the miss named.
  std::vector<std::string> lines = lines_of(slurp(path("s2.jsonl")));
  nlohmann::json j = nlohmann::json::parse(lines[1]);
  j["missed"] = {42};
  lines[1] = j.dump();
  spit(path("s2.jsonl"), lines[0] + "\n" + lines[1] + "\n");
  r = run({"verify-merge", path("s0.jsonl"), path("s1.jsonl"), path("s2.jsonl"), "--out", path("m.jsonl")});
  EXPECT_EQ(r.status, 3) << r.err;
  EXPECT_THAT(r.err, HasSubstr("MISS: frame 11: 1 visible object(s) not in the PVS: [42]"));
  EXPECT_THAT(r.err, HasSubstr("1 missed object-frames in 1 frames"));
}

}  // namespace
}  // namespace voxvis::test
