// `voxvis export` run as a separate process (VOXVIS_CLI): the file it writes
// read back with OpenVDB and checked against `voxvis replay`'s answer for
// the same frame, and every refusal: exit status 2, a message naming the
// problem, no output file and no temporary file left behind.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <openvdb/openvdb.h>
#include <openvdb/io/File.h>

#include "cli_runner.h"
#include "files.h"

namespace voxvis::test {
namespace {

using ::testing::HasSubstr;

// A wall across the view (id 1), a sphere behind it (id 2, hidden) and a
// dynamic sphere before it (id 3) that the frames move.
constexpr const char* kScene = R"({
  "format": "voxvis-scene/1",
  "bounds": {"min": [0, 0, 0], "max": [20, 20, 20]},
  "grid": [16, 16, 16],
  "objects": [
    {"id": 1, "shape": "box", "min": [0, 0, 12.5], "max": [20, 20, 13.75]},
    {"id": 2, "shape": "sphere", "center": [10, 10, 17], "radius": 1.5},
    {"id": 3, "shape": "sphere", "center": [9, 11, 6], "radius": 1, "dynamic": true, "max_speed": 5}
  ]
}
)";

std::string frames_text(int n) {
  std::ostringstream s;
  for (int i = 0; i < n; ++i)
    s << "{\"t\": " << 0.1 * i << ", \"eye\": [10, 10, 1], \"dir\": [0, 0, 1], \"up\": [0, 1, 0], "
      << "\"fov_y_deg\": 60, \"aspect\": 1.5, \"near\": 0.05, \"far\": 100, \"moves\": [{\"id\": 3, \"center\": ["
      << 9 + 0.3 * i << ", 11, 6]}]}\n";
  return s.str();
}

class ExportCli : public Cli {
 protected:
  void SetUp() override {
    Cli::SetUp();
    openvdb::initialize();
    spit(path("scene.json"), kScene);
    spit(path("frames.jsonl"), frames_text(5));
  }

  /// Names of the grids in a .vdb file, sorted.
  static std::vector<std::string> grid_names(const std::string& file_name) {
    openvdb::io::File file(file_name);
    file.open();
    std::vector<std::string> names;
    for (auto it = file.beginName(); it != file.endName(); ++it) names.push_back(it.gridName());
    file.close();
    std::sort(names.begin(), names.end());
    return names;
  }

  void expect_refused(const Result& r, const std::string& what) {
    EXPECT_EQ(r.signal, 0) << r.err;
    EXPECT_EQ(r.status, 2) << r.err;
    EXPECT_THAT(r.err, HasSubstr("voxvis: error: "));
    EXPECT_THAT(r.err, HasSubstr(what));
    EXPECT_FALSE(std::filesystem::exists(path("out.vdb")));
    EXPECT_EQ(files(), (std::vector<std::string>{"frames.jsonl", "scene.json"}));
  }
};

TEST_F(ExportCli, WritesTheFramesGridsAsReplayComputesIt) {
  const Result r = run({"export", "--scene", path("scene.json"), "--frames", path("frames.jsonl"), "--frame", "3",
                        "--vdb", path("out.vdb")});
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(r.out, "");
  EXPECT_THAT(r.err, HasSubstr("wrote " + path("out.vdb")));
  EXPECT_EQ(grid_names(path("out.vdb")), (std::vector<std::string>{"objects", "occluded", "opaque", "pvs", "visited"}));

  // The same frame through `voxvis replay`: the file's PVS size and time are
  // its frame 3's.
  const Result rep = run({"replay", "--scene", path("scene.json"), "--frames", path("frames.jsonl"), "-q"});
  ASSERT_EQ(rep.status, 0) << rep.err;
  const std::vector<std::string> lines = lines_of(rep.out);
  ASSERT_EQ(lines.size(), 5u);
  const nlohmann::json j = nlohmann::json::parse(lines[3]);
  openvdb::io::File file(path("out.vdb"));
  ASSERT_TRUE(file.open());
  const openvdb::MetaMap::Ptr meta = file.getMetadata();
  EXPECT_EQ(meta->metaValue<std::int64_t>("voxvis_frame"), 3);
  EXPECT_EQ(meta->metaValue<std::int64_t>("voxvis_pvs_size"), static_cast<std::int64_t>(j.at("pvs").size()));
  EXPECT_DOUBLE_EQ(meta->metaValue<double>("voxvis_time"), 0.3);
  EXPECT_EQ(meta->metaValue<std::string>("voxvis_scene"), path("scene.json"));
  EXPECT_EQ(j.at("pvs"), nlohmann::json::array({1, 3}));
  // The dynamic sphere where frame 3 moved it, (9.9, 11, 6): voxel (7, 8, 4).
  const auto objects = openvdb::gridPtrCast<openvdb::Int32Grid>(file.readGrid("objects"));
  ASSERT_TRUE(objects);
  EXPECT_EQ(objects->tree().getValue(openvdb::Coord(7, 8, 4)), 1);
  // The wall's layer (world z 12.5 to 13.75, voxels of 1.25: grid z 10) is
  // opaque over the whole cross-section, and nothing else.
  const auto opaque = openvdb::gridPtrCast<openvdb::BoolGrid>(file.readGrid("opaque"));
  ASSERT_TRUE(opaque);
  EXPECT_EQ(opaque->activeVoxelCount(), 16u * 16u);
  EXPECT_TRUE(opaque->tree().isValueOn(openvdb::Coord(0, 15, 10)));
  file.close();
  EXPECT_EQ(files(), (std::vector<std::string>{"frames.jsonl", "out.vdb", "scene.json"}));
}

TEST_F(ExportCli, SceneAloneAndTheVoxelTraversal) {
  Result r = run({"export", "--scene", path("scene.json"), "--vdb", path("out.vdb"), "-q"});
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(r.err, "");
  EXPECT_EQ(grid_names(path("out.vdb")), (std::vector<std::string>{"objects", "opaque"}));
  r = run({"export", "--scene", path("scene.json"), "--frames", path("frames.jsonl"), "--frame", "0",
           "--occlusion-buffer", "0", "--vdb", path("out.vdb")});
  ASSERT_EQ(r.status, 0) << r.err;
  openvdb::io::File file(path("out.vdb"));
  ASSERT_TRUE(file.open());
  EXPECT_EQ(file.getMetadata()->metaValue<std::string>("voxvis_traversal"), "voxels");
  EXPECT_EQ(file.getMetadata()->metaValue<std::int32_t>("voxvis_occlusion_buffer"), 0);
  file.close();
}

TEST_F(ExportCli, RefusesBadFrames) {
  expect_refused(run({"export", "--scene", path("scene.json"), "--frames", path("frames.jsonl"), "--frame", "-1",
                      "--vdb", path("out.vdb")}),
                 "--frame: must be a 0-based frame index >= 0, got -1");
  expect_refused(run({"export", "--scene", path("scene.json"), "--frames", path("frames.jsonl"), "--frame", "5",
                      "--vdb", path("out.vdb")}),
                 path("frames.jsonl") + ": --frame: frame 5 is beyond the file's 5 frames (0 to 4)");
  expect_refused(run({"export", "--scene", path("scene.json"), "--frame", "2", "--vdb", path("out.vdb")}),
                 "--frame requires --frames");
  expect_refused(run({"export", "--scene", path("scene.json"), "--frames", path("frames.jsonl"), "--vdb",
                      path("out.vdb")}),
                 "--frames requires --frame");
  expect_refused(run({"export", "--scene", path("scene.json"), "--frames", path("frames.jsonl"), "--frame", "x",
                      "--vdb", path("out.vdb")}),
                 "--frame");
}

TEST_F(ExportCli, RefusesBadScenesAndOutputs) {
  spit(path("scene.json"), std::string(kScene).replace(std::string(kScene).find("\"radius\": 1.5"), 13,
                                                       "\"radius\": -1.5"));
  expect_refused(run({"export", "--scene", path("scene.json"), "--vdb", path("out.vdb")}),
                 path("scene.json") + ":7: objects[1].radius: must be > 0, got -1.5");
  spit(path("scene.json"), kScene);
  expect_refused(run({"export", "--scene", path("scene.json"), "--vdb", path("no-such-dir/out.vdb")}),
                 path("no-such-dir/out.vdb") + ": cannot create");
  expect_refused(run({"export", "--scene", path("scene.json"), "--vdb", "-"}), "--vdb: must name a file");
  expect_refused(run({"export", "--scene", path("missing.json"), "--vdb", path("out.vdb")}),
                 path("missing.json") + ": cannot open");
}

TEST_F(ExportCli, AFailedRunLeavesAnEarlierFileWhole) {
  spit(path("out.vdb"), "earlier");
  // Line 3 moves a static object: the replay fails before frame 3.
  std::string text = frames_text(5);
  std::vector<std::string> lines = lines_of(text);
  lines[2] = lines[2].substr(0, lines[2].find("\"moves\"")) + "\"moves\": [{\"id\": 1, \"center\": [10, 10, 13]}]}";
  std::string bad;
  for (const std::string& l : lines) bad += l + "\n";
  spit(path("frames.jsonl"), bad);
  const Result r = run({"export", "--scene", path("scene.json"), "--frames", path("frames.jsonl"), "--frame", "3",
                        "--vdb", path("out.vdb")});
  EXPECT_EQ(r.status, 2) << r.err;
  EXPECT_THAT(r.err, HasSubstr(path("frames.jsonl") + ":3: moves[0].id: object 1 is static"));
  EXPECT_EQ(slurp(path("out.vdb")), "earlier");
  EXPECT_EQ(files(), (std::vector<std::string>{"frames.jsonl", "out.vdb", "scene.json"}));
}

}  // namespace
}  // namespace voxvis::test
