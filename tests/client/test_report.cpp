// `voxvis report`: its pure part in process (configurations, Pareto rows,
// the table), and the command on a small scene: rows that agree with
// `replay` and `verify` run by hand, the CPU ray caster's reference against
// the ray caster run by hand, the reference where no EGL is available, a
// configuration that cannot run next to ones that do, bad configuration files.
#include <algorithm>
#include <cstdint>
#include <iterator>
#include <string>
#include <unordered_map>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "cli_runner.h"
#include "files.h"
#include "report_model.h"
#include "voxvis/format.h"
#include "voxvis/generate.h"
#include "voxvis/raycast.h"

namespace voxvis::test {
namespace {

using cli::ReportConfig;
using cli::ReportRow;
using ::testing::HasSubstr;

ReportRow row(const std::string& name, double ms, double tightness, std::uint64_t misses = 0) {
  ReportRow r;
  r.name = name;
  r.median_ms = ms;
  r.tightness = tightness;
  r.misses = misses;
  return r;
}

TEST(ReportModel, ParetoRowsAreThoseNoConservativeRowBeats) {
  std::vector<ReportRow> rows = {row("fast loose", 1.0, 3.0),   row("slow tight", 10.0, 1.1),
                                 row("dominated", 5.0, 3.5),    row("middle", 4.0, 1.5),
                                 row("tie a", 4.0, 1.5),        row("misses", 0.5, 0.9, 12),
                                 row("same time, looser", 1.0, 3.2)};
  ReportRow failed = row("failed", 0.1, 0.1);
  failed.error = "EGL: none";
  rows.push_back(failed);
  cli::mark_pareto(&rows);
  std::vector<std::string> pareto;
  for (const ReportRow& r : rows)
    if (r.pareto) pareto.push_back(r.name);
  EXPECT_EQ(pareto, (std::vector<std::string>{"fast loose", "slow tight", "middle", "tie a"}));

  const std::string md = cli::report_markdown(rows, "64x36");
  // Sorted by time, failed last, Pareto starred, misses flagged.
  EXPECT_LT(md.find("| misses |"), md.find("| fast loose |"));
  EXPECT_LT(md.find("| fast loose |"), md.find("| middle |"));
  EXPECT_LT(md.find("| middle |"), md.find("| slow tight |"));
  EXPECT_LT(md.find("| slow tight |"), md.find("| failed | could not run: EGL: none"));
  EXPECT_THAT(md, HasSubstr("| fast loose | 1.00 | 0.00 | 0.00 | 3.000 | 0 | 0 | * |"));
  EXPECT_THAT(md, HasSubstr("| dominated | 5.00 | 0.00 | 0.00 | 3.500 | 0 | 0 |  |"));
}

TEST(ReportModel, ConfigurationFilesAndTheirErrors) {
  std::vector<ReportConfig> c;
  std::string message;
  ASSERT_TRUE(cli::parse_configs(
      R"({"configs": [{"name": "a"}, {"name": "b", "grid": [10, 20, 30], "occlusion_buffer": 0, "level": "queries"}]})",
      "c.json", &c, &message))
      << message;
  ASSERT_EQ(c.size(), 2u);
  EXPECT_EQ(c[0].occlusion_buffer, 160);
  EXPECT_EQ(c[0].level, "none");
  EXPECT_FALSE(c[0].grid.has_value());
  EXPECT_EQ(*c[1].grid, glm::ivec3(10, 20, 30));
  EXPECT_EQ(c[1].occlusion_buffer, 0);
  const std::pair<const char*, const char*> bad[] = {
      {"[]", "c.json: expected {\"configs\": [ ... ]}"},
      {R"({"configs": []})", "at least one configuration"},
      {R"({"configs": [{"grid": [1, 2, 3]}]})", "c.json: configs[0].name: missing"},
      {R"({"configs": [{"name": "a"}, {"name": "a"}]})", "configs[1].name: 'a' is used twice"},
      {R"({"configs": [{"name": "a", "grid": [1, 2]}]})", "configs[0].grid: expected [NX, NY, NZ]"},
      {R"({"configs": [{"name": "a", "grid": [1, 0, 3]}]})", "configs[0].grid: each resolution"},
      {R"({"configs": [{"name": "a", "occlusion_buffer": 7}]})", "configs[0].occlusion_buffer: must be 0"},
      {R"({"configs": [{"name": "a", "level": 3}]})", "configs[0].level: not a string"},
      {R"({"configs": [{"name": "a", "colour": "red"}]})", "configs[0].colour: unknown field"},
  };
  for (const auto& [text, what] : bad) {
    EXPECT_FALSE(cli::parse_configs(text, "c.json", &c, &message)) << text;
    EXPECT_THAT(message, HasSubstr(what)) << text;
  }
  // The default sweep: buffer sizes, grids and levels, names unique.
  const std::vector<ReportConfig> d = cli::default_configs(glm::ivec3(100, 60, 100));
  ASSERT_GE(d.size(), 9u);
  EXPECT_EQ(d[0].name, "buffer off");
  bool half = false, levels = false;
  for (const ReportConfig& x : d) {
    half |= x.grid && *x.grid == glm::ivec3(50, 30, 50);
    levels |= x.level == "hierarchical";
  }
  EXPECT_TRUE(half);
  EXPECT_TRUE(levels);
}

class Report : public Cli {
 protected:
  /// The ray caster's exactly visible set of every frame of `frames` (the
  /// scene's moves applied), through the pixel centres of w x h.
  /// `pick` on every frame's objects (moves applied) and camera.
  template <class Pick>
  std::vector<std::vector<ObjectId>> by_hand(const std::string& scene, const std::string& frames, Pick pick) {
    SceneDesc desc;
    FormatError error;
    EXPECT_TRUE(parse_scene(slurp(path(scene)), scene, &desc, &error)) << error.str();
    std::unordered_map<ObjectId, std::size_t> slot;
    for (std::size_t i = 0; i < desc.objects.size(); ++i) slot[desc.objects[i].id] = i;
    std::vector<std::vector<ObjectId>> sets;
    int line = 0;
    for (const std::string& l : lines_of(slurp(path(frames)))) {
      FrameInput f;
      EXPECT_TRUE(parse_frame_line(l, frames, ++line, &f, &error)) << error.str();
      for (const Move& m : f.moves) desc.objects[slot.at(m.id)].center = m.center;
      sets.push_back(pick(desc.objects, f.camera));
    }
    return sets;
  }
  std::vector<std::vector<ObjectId>> cast_by_hand(const std::string& scene, const std::string& frames, int w,
                                                   int h) {
    return by_hand(scene, frames, [&](const std::vector<ObjectDesc>& objects, const Camera& cam) {
      return raycast::visible_objects(objects, cam, raycast::pixel_centres(w, h));
    });
  }
};

TEST_F(Report, RowsAgreeWithReplayAndVerifyAndAFailedConfigurationLeavesTheOthers) {
  write_paper("s.json", "f.jsonl", 300, 30, 8);
  spit(path("c.json"), R"({"configs": [
    {"name": "off", "occlusion_buffer": 0},
    {"name": "default"},
    {"name": "queries", "level": "queries"},
    {"name": "too big", "grid": [4096, 4096, 4096]}]})");
  Result r = run({"report", "--scene", path("s.json"), "--frames", path("f.jsonl"), "--configs", path("c.json"),
                  "--out", path("out"), "--resolution", "128x72", "-q"});
  EXPECT_EQ(r.status, 2) << r.err;  // One configuration failed.
  EXPECT_THAT(r.err, HasSubstr("configuration 'too big' could not run"));
  const nlohmann::json rep = nlohmann::json::parse(slurp(path("out/report.json")));
  ASSERT_EQ(rep["rows"].size(), 5u);  // And the frustum-culling baseline, last.
  EXPECT_TRUE(rep["rows"][3].contains("error"));
  EXPECT_EQ(rep["rows"][4]["name"], "frustum culling only");
  EXPECT_EQ(slurp(path("out/tradeoff.png")).substr(1, 3), "PNG");
  EXPECT_THAT(slurp(path("out/report.md")), HasSubstr("| too big | could not run:"));

  // By hand: replay's PVS for "off", verify's exact set at the same pixels.
  r = run({"replay", "--scene", path("s.json"), "--frames", path("f.jsonl"), "--occlusion-buffer", "0", "--out",
           path("off.jsonl"), "-q"});
  ASSERT_EQ(r.status, 0) << r.err;
  r = run({"verify", "--scene", path("s.json"), "--frames", path("f.jsonl"), "--pvs", path("off.jsonl"),
           "--resolution", "128x72", "-q"});
  ASSERT_EQ(r.status, 0) << r.err;
  std::uint64_t pvs = 0, visible = 0;
  for (const std::string& l : lines_of(r.out)) {
    const nlohmann::json j = nlohmann::json::parse(l);
    pvs += j["pvs_size"].get<std::uint64_t>();
    visible += j["visible"].size();
  }
  ASSERT_GT(visible, 0u);
  EXPECT_EQ(rep["exactly_visible_total"].get<std::uint64_t>(), visible);
  const nlohmann::json& off = rep["rows"][0];
  EXPECT_EQ(off["name"], "off");
  EXPECT_EQ(off["frames"].get<int>(), 8);
  EXPECT_DOUBLE_EQ(off["tightness"].get<double>(), static_cast<double>(pvs) / static_cast<double>(visible));
  EXPECT_EQ(off["misses"].get<int>(), 0);
  // Refinement keeps every visible object and tightens.
  const nlohmann::json& q = rep["rows"][2];
  EXPECT_EQ(q["misses"].get<int>(), 0);
  EXPECT_LT(q["tightness"].get<double>(), rep["rows"][1]["tightness"].get<double>());
  EXPECT_GE(q["tightness"].get<double>(), 1.0);
  EXPECT_GT(q["queries_per_frame"].get<double>(), 0.0);
  // Its costs: a draw call per query and the depth pass; time split.
  EXPECT_GE(q["refinement"]["draw_calls_per_frame"].get<double>(), q["queries_per_frame"].get<double>() + 1.0);
  EXPECT_GT(q["refinement"]["samples_passed_per_frame"].get<double>(), 0.0);
  EXPECT_GT(q["refinement"]["draw_ms_mean"].get<double>(), 0.0);
  EXPECT_GT(q["refinement"]["wait_ms_mean"].get<double>(), 0.0);
  EXPECT_EQ(off["refinement"]["draw_calls_per_frame"].get<double>(), 0.0);
}

// Before: on the voxel world, report counted EGL's edge-only sightings (its
// single precision) as misses — 17 in the default row, which left the
// engine's default off the Pareto front — where verify of the same PVS
// dismissed them as not visible. Both now take a miss by one definition
// (client/reference.h, confirm_misses).
TEST_F(Report, ReportAndVerifyCountMissesByOneDefinition) {
  Result r = run({"generate", "--preset", "voxel-world", "--frames", "30", "--scene-out", path("w.json"),
                  "--frames-out", path("w.jsonl")});
  ASSERT_EQ(r.status, 0) << r.err;
  spit(path("c.json"), R"({"configs": [{"name": "default"}]})");
  r = run({"report", "--scene", path("w.json"), "--frames", path("w.jsonl"), "--configs", path("c.json"), "--out",
           path("out"), "--reference", "auto", "-q"});
  ASSERT_EQ(r.status, 0) << r.err;
  const nlohmann::json rep = nlohmann::json::parse(slurp(path("out/report.json")));
  if (rep["reference_source"] != "egl") GTEST_SKIP() << "no EGL here: the ray caster's sets need no confirmation";
  const nlohmann::json& row = rep["rows"][0];
  ASSERT_EQ(row["name"], "default");
  r = run({"replay", "--scene", path("w.json"), "--frames", path("w.jsonl"), "--out", path("pvs.jsonl"), "-q"});
  ASSERT_EQ(r.status, 0) << r.err;
  r = run({"verify", "--scene", path("w.json"), "--frames", path("w.jsonl"), "--pvs", path("pvs.jsonl"),
           "--reference", "egl", "-q"});
  ASSERT_EQ(r.status, 0) << r.err;
  std::uint64_t missed = 0, edge_only = 0;
  for (const std::string& l : lines_of(r.out)) {
    const nlohmann::json j = nlohmann::json::parse(l);
    missed += j["missed"].size();
    edge_only += j["edge_only"].size();
  }
  EXPECT_EQ(row["misses"].get<std::uint64_t>(), missed);
  EXPECT_EQ(row["edge_only_dismissed"].get<std::uint64_t>(), edge_only);
  EXPECT_EQ(missed, 0u);
  EXPECT_TRUE(row["pareto"].get<bool>()) << "no miss: on the front";
  // llvmpipe shows 3 such edge sightings on these frames (measured); a GPU
  // may show others.
  if (rep["reference"].get<std::string>().find("llvmpipe") != std::string::npos) {
    EXPECT_GT(edge_only, 0u) << "the case this test is for";
  }
  if (edge_only > 0) {
    EXPECT_THAT(slurp(path("out/report.md")), HasSubstr(std::to_string(edge_only) + " such object-frames were dismissed"));
  }
}

TEST_F(Report, TheRayCastersReferenceIsTheRayCasterRunByHand) {
  write_paper("s.json", "f.jsonl", 300, 30, 6);
  spit(path("c.json"), R"({"configs": [{"name": "off", "occlusion_buffer": 0}, {"name": "default"}]})");
  Result r = run({"report", "--scene", path("s.json"), "--frames", path("f.jsonl"), "--configs", path("c.json"),
                  "--out", path("out"), "--resolution", "96x54", "--reference", "raycast"});
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_THAT(r.err, HasSubstr("exactly visible sets at 96x54 (CPU ray caster"));
  const nlohmann::json rep = nlohmann::json::parse(slurp(path("out/report.json")));
  EXPECT_EQ(rep["reference_source"], "raycast");
  EXPECT_THAT(rep["reference"].get<std::string>(), HasSubstr("96x54 (CPU ray caster"));
  EXPECT_THAT(slurp(path("out/report.md")), HasSubstr("exact at 96x54 (CPU ray caster"));

  // By hand: the caster through the same pixel centres, replay's PVS.
  const std::vector<std::vector<ObjectId>> exact = cast_by_hand("s.json", "f.jsonl", 96, 54);
  ASSERT_EQ(exact.size(), 6u);
  std::uint64_t exact_total = 0;
  for (const auto& e : exact) exact_total += e.size();
  ASSERT_GT(exact_total, 0u);
  EXPECT_EQ(rep["exactly_visible_total"].get<std::uint64_t>(), exact_total);
  const std::pair<const char*, const char*> configs[] = {{"off", "0"}, {"default", "160"}};
  for (std::size_t i = 0; i < 2; ++i) {
    r = run({"replay", "--scene", path("s.json"), "--frames", path("f.jsonl"), "--occlusion-buffer",
             configs[i].second, "--out", path("pvs.jsonl"), "-q"});
    ASSERT_EQ(r.status, 0) << r.err;
    const std::vector<std::string> lines = lines_of(slurp(path("pvs.jsonl")));
    ASSERT_EQ(lines.size(), exact.size());
    std::uint64_t pvs_total = 0, misses = 0;
    for (std::size_t k = 0; k < lines.size(); ++k) {
      const nlohmann::json line = nlohmann::json::parse(lines[k]);
      std::vector<ObjectId> pvs;
      for (const auto& id : line["pvs"]) pvs.push_back(id.get<ObjectId>());
      std::sort(pvs.begin(), pvs.end());
      pvs_total += pvs.size();
      std::vector<ObjectId> missed;
      std::set_difference(exact[k].begin(), exact[k].end(), pvs.begin(), pvs.end(), std::back_inserter(missed));
      misses += missed.size();
    }
    const nlohmann::json& row = rep["rows"][i];
    EXPECT_EQ(row["name"], configs[i].first);
    EXPECT_DOUBLE_EQ(row["tightness"].get<double>(),
                     static_cast<double>(pvs_total) / static_cast<double>(exact_total))
        << configs[i].first;
    EXPECT_EQ(row["misses"].get<std::uint64_t>(), misses) << configs[i].first;
  }
  // The baseline: plain frustum culling of the same frames, by hand.
  std::uint64_t frustum_total = 0;
  for (const auto& set : by_hand("s.json", "f.jsonl", raycast::frustum_objects)) frustum_total += set.size();
  ASSERT_EQ(rep["rows"].size(), 3u);
  const nlohmann::json& vfc = rep["rows"][2];
  EXPECT_EQ(vfc["name"], "frustum culling only");
  EXPECT_DOUBLE_EQ(vfc["tightness"].get<double>(),
                   static_cast<double>(frustum_total) / static_cast<double>(exact_total));
  EXPECT_EQ(vfc["misses"].get<std::uint64_t>(), 0u);
  EXPECT_GT(vfc["tightness"].get<double>(), rep["rows"][1]["tightness"].get<double>())
      << "the occlusion culler is no tighter than frustum culling";
}

TEST_F(Report, LevelsThatKeepStateStartAfreshForEachConfiguration) {
  write_paper("s.json", "f.jsonl", 300, 30, 6);
  spit(path("c.json"), R"({"configs": [
    {"name": "ternary 1", "level": "ternary"}, {"name": "ternary 2", "level": "ternary"},
    {"name": "near-optimal 1", "level": "near-optimal"}, {"name": "near-optimal 2", "level": "near-optimal"}]})");
  Result r = run({"report", "--scene", path("s.json"), "--frames", path("f.jsonl"), "--configs", path("c.json"),
                  "--out", path("out"), "--resolution", "96x54", "--cost-model", path("model.json")});
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_THAT(r.err, HasSubstr("near-optimal: cost model measured in"));
  EXPECT_THAT(r.err, HasSubstr("saved to " + path("model.json")));
  const nlohmann::json rep = nlohmann::json::parse(slurp(path("out/report.json")));
  ASSERT_EQ(rep["rows"].size(), 5u);
  for (std::size_t i : {0u, 2u}) {
    EXPECT_EQ(rep["rows"][i]["tightness"], rep["rows"][i + 1]["tightness"]) << rep["rows"][i]["name"];
    EXPECT_EQ(rep["rows"][i]["queries_per_frame"], rep["rows"][i + 1]["queries_per_frame"]) << rep["rows"][i]["name"];
    EXPECT_EQ(rep["rows"][i]["misses"].get<int>(), 0);
  }
  // A second report loads the model.
  r = run({"report", "--scene", path("s.json"), "--frames", path("f.jsonl"), "--configs", path("c.json"),
           "--out", path("out2"), "--resolution", "96x54", "--cost-model", path("model.json")});
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_THAT(r.err, HasSubstr("near-optimal: cost model loaded from " + path("model.json")));
}

TEST_F(Report, WithoutEglTheRayCasterIsTheReferenceAndOnlyLevelsFail) {
  write_paper("s.json", "f.jsonl", 200, 20, 4);
  spit(path("c.json"), R"({"configs": [{"name": "default"}, {"name": "queries", "level": "queries"}]})");
  const std::vector<std::string> no_egl = {"__EGL_VENDOR_LIBRARY_FILENAMES=/nonexistent/voxvis-no-egl.json"};
  const std::vector<std::string> args = {"report", "--scene", path("s.json"), "--frames", path("f.jsonl"),
                                         "--configs", path("c.json"), "--resolution", "64x36"};
  auto with = [&](std::vector<std::string> extra) {
    std::vector<std::string> a = args;
    a.insert(a.end(), extra.begin(), extra.end());
    return a;
  };
  // auto, the default: the ray caster, said on stderr and in the header.
  Result r = run(with({"--out", path("auto")}), no_egl);
  EXPECT_EQ(r.status, 2) << r.err;  // The level's row failed.
  EXPECT_THAT(r.err, HasSubstr("EGL: no EGL implementation found"));
  EXPECT_THAT(r.err, HasSubstr("the exact reference is the CPU ray caster"));
  EXPECT_THAT(r.err, HasSubstr("configuration 'queries' could not run: EGL: no EGL implementation found"));
  const nlohmann::json rep = nlohmann::json::parse(slurp(path("auto/report.json")));
  EXPECT_EQ(rep["reference_source"], "raycast");
  ASSERT_EQ(rep["rows"].size(), 3u);
  EXPECT_FALSE(rep["rows"][0].contains("error"));
  EXPECT_TRUE(rep["rows"][0]["tightness"].is_number());
  EXPECT_THAT(rep["rows"][1]["error"].get<std::string>(), HasSubstr("EGL: no EGL implementation found"));
  EXPECT_THAT(slurp(path("auto/report.md")), HasSubstr("exact at 64x36 (CPU ray caster"));
  // The same numbers as --reference raycast.
  r = run(with({"--out", path("raycast"), "--reference", "raycast", "-q"}), no_egl);
  EXPECT_EQ(r.status, 2) << r.err;
  const nlohmann::json cast = nlohmann::json::parse(slurp(path("raycast/report.json")));
  EXPECT_EQ(cast["exactly_visible_total"], rep["exactly_visible_total"]);
  EXPECT_EQ(cast["rows"][0]["tightness"], rep["rows"][0]["tightness"]);
  EXPECT_EQ(cast["rows"][0]["misses"], rep["rows"][0]["misses"]);
  // egl insists.
  r = run(with({"--out", path("egl"), "--reference", "egl"}), no_egl);
  EXPECT_EQ(r.status, 2) << r.err;
  EXPECT_THAT(r.err, HasSubstr("voxvis: error: EGL: no EGL implementation found"));
}

TEST_F(Report, BadConfigurationFilesAreErrorsNamingTheEntry) {
  spit(path("s.json"), scene_to_json(make_paper_scene(PaperSceneParams{})));
  spit(path("f.jsonl"), "");
  spit(path("c.json"), R"({"configs": [{"name": "x", "level": "magic"}]})");
  Result r = run({"report", "--scene", path("s.json"), "--frames", path("f.jsonl"), "--configs", path("c.json"),
                  "--out", path("out")});
  EXPECT_EQ(r.status, 2);
  EXPECT_THAT(r.err, HasSubstr("c.json: configs[0].level: unknown level 'magic'"));
  spit(path("c.json"), R"({"configs": [{"name": "x", "occlusion_buffer": -1}]})");
  r = run({"report", "--scene", path("s.json"), "--frames", path("f.jsonl"), "--configs", path("c.json")});
  EXPECT_EQ(r.status, 2);
  EXPECT_THAT(r.err, HasSubstr("configs[0].occlusion_buffer: must be 0"));
  r = run({"report", "--scene", path("s.json"), "--frames", path("f.jsonl"), "--egl-device", "-2"});
  EXPECT_EQ(r.status, 2);
  EXPECT_THAT(r.err, HasSubstr("--egl-device: must be >= 0"));
  r = run({"report", "--scene", path("s.json"), "--frames", path("f.jsonl"), "--reference", "gpu"});
  EXPECT_EQ(r.status, 2);
  EXPECT_THAT(r.err, HasSubstr("voxvis: error: --reference: unknown reference 'gpu' (known: auto, egl, raycast)"));
  r = run({"report", "--scene", path("s.json"), "--frames", path("f.jsonl"), "--resolution", "0x4"});
  EXPECT_EQ(r.status, 2);
  EXPECT_THAT(r.err, HasSubstr("--resolution: width and height must be >= 1"));
  spit(path("c.json"), R"({"configs": [{"name": "x"}]})");
  r = run({"report", "--scene", path("s.json"), "--frames", path("f.jsonl"), "--configs", path("c.json"),
           "--out", path("out")});
  EXPECT_EQ(r.status, 2);
  EXPECT_THAT(r.err, HasSubstr("f.jsonl: no frames"));
}

TEST_F(Report, WithoutGnuplotTheTablesAreStillWritten) {
  write_paper("s.json", "f.jsonl", 100, 0, 3);
  spit(path("c.json"), R"({"configs": [{"name": "default"}]})");
  const Result r = run({"report", "--scene", path("s.json"), "--frames", path("f.jsonl"), "--configs",
                        path("c.json"), "--out", path("it's here"), "--resolution", "64x36", "-q"},
                       {"PATH=/nonexistent"});
  EXPECT_EQ(r.status, 2);
  EXPECT_THAT(r.err, HasSubstr("tradeoff.png: cannot run gnuplot"));
  EXPECT_THAT(r.err, HasSubstr("install gnuplot-nox"));
  EXPECT_THAT(slurp(path("it's here/report.md")), HasSubstr("| default |"));
}

}  // namespace
}  // namespace voxvis::test
