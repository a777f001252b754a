// `voxvis view` against the real server reproduces `voxvis replay` line for
// line: the same scene and frames (with moves) through the network give the
// same PVS, wake lists and counters as the batch engine.
#include <filesystem>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "server_process.h"

namespace voxvis::servertest {
namespace {

namespace fs = std::filesystem;

/// Compares two output files of `voxvis replay` format: every line's frame,
/// pvs, wake and every stats counter but time_us.
void expect_same_output(const std::string& expected_text, const std::string& actual_text,
                        const std::string& what) {
  const std::vector<std::string> expected = lines_of(expected_text);
  const std::vector<std::string> actual = lines_of(actual_text);
  ASSERT_EQ(actual.size(), expected.size()) << what;
  for (std::size_t i = 0; i < expected.size(); ++i) {
    SCOPED_TRACE(what + ", line " + std::to_string(i + 1));
    const nlohmann::json e = nlohmann::json::parse(expected[i], nullptr, false);
    const nlohmann::json a = nlohmann::json::parse(actual[i], nullptr, false);
    ASSERT_FALSE(e.is_discarded()) << expected[i];
    ASSERT_FALSE(a.is_discarded()) << actual[i];
    EXPECT_EQ(a.at("frame"), e.at("frame"));
    EXPECT_EQ(a.at("pvs"), e.at("pvs"));
    EXPECT_EQ(a.at("wake"), e.at("wake"));
    nlohmann::json es = e.at("stats"), as = a.at("stats");
    ASSERT_TRUE(es.contains("time_us"));
    ASSERT_TRUE(as.contains("time_us"));
    es.erase("time_us");
    as.erase("time_us");
    EXPECT_EQ(as, es);
  }
}

TEST(ServerCli, ViewMatchesReplay) {
  const std::string examples = std::string(VOXVIS_SOURCE_DIR) + "/examples/paper";
  ServerProcess server;
  // Two scenes from the file, one per run (a run moves objects and advances
  // the scene's clock): one named by its file's stem, one by --scene ID=FILE.
  const std::string scene_full = server.path("paper_full.json");
  fs::copy_file(examples + "/scene.json", scene_full);
  // 40 frames: every line of the example moves the 200 dynamic objects.
  const std::vector<std::string> all_frames = lines_of(slurp(examples + "/frames.jsonl"));
  ASSERT_GE(all_frames.size(), 40u);
  std::string frames_text;
  for (std::size_t i = 0; i < 40; ++i) frames_text += all_frames[i] + "\n";
  ASSERT_NE(frames_text.find("\"moves\""), std::string::npos);
  const std::string frames = server.path("frames.jsonl");
  spit(frames, frames_text);

  server.extra_args() = {"--scene", scene_full, "--scene",
                         "paper_delta=" + examples + "/scene.json"};
  ASSERT_TRUE(server.start());
  std::vector<std::string> ids;
  ASSERT_TRUE(server.api().list_scenes(&ids).ok());
  ASSERT_EQ(ids, (std::vector<std::string>{"paper_delta", "paper_full"}));

  const std::string replay_out = server.path("replay.jsonl");
  ProcessResult r = run_program({VOXVIS_CLI, "replay", "--scene", examples + "/scene.json",
                                 "--frames", frames, "--out", replay_out, "-q"},
                                server.dir());
  ASSERT_EQ(r.status, 0) << r.err;
  const std::string expected = slurp(replay_out);
  ASSERT_EQ(lines_of(expected).size(), 40u);

  const std::string view_out = server.path("view.jsonl");
  r = run_program({VOXVIS_CLI, "view", "--server", server.address(), "--scene", "paper_full",
                   "--frames", frames, "--out", view_out, "-q"},
                  server.dir());
  ASSERT_EQ(r.status, 0) << r.err;
  expect_same_output(expected, slurp(view_out), "voxvis view");

  const std::string delta_out = server.path("view_delta.jsonl");
  r = run_program({VOXVIS_CLI, "view", "--server", server.address(), "--scene", "paper_delta",
                   "--frames", frames, "--out", delta_out, "-q", "--delta"},
                  server.dir());
  ASSERT_EQ(r.status, 0) << r.err;
  expect_same_output(expected, slurp(delta_out), "voxvis view --delta");

  v1::SceneInfo info;
  ASSERT_TRUE(server.api().stats("paper_full", &info).ok());
  EXPECT_EQ(info.frames_served(), 40u);
  EXPECT_EQ(info.moves_applied(), 40u * 200u);
  // The CLI's streams are closed: the server lets go of them.
  EXPECT_TRUE(wait_until(
      [&] { return server.api().stats("paper_full", &info).ok() && info.viewers() == 0; },
      Seconds(10)))
      << "viewers " << info.viewers();
  EXPECT_EQ(server.terminate(), 0);
}

// Many viewers of one scene at once: their frames run in parallel on the
// server and share the scene's clock; every stream must be answered without
// error (a frame racing another's clock once failed with "time goes
// backwards"), and the report must count what was answered.
// The scene's clock follows its simulation and a viewer may lead it by at
// most --max-view-lead: `voxvis view` passes every frame's time through the
// simulation stream once the file has moved something, so frames without
// moves, long after the last one, still match `replay`.
TEST(ServerCli, ViewMatchesReplayWhenMovesStop) {
  ServerProcess server;
  const std::string scene = server.path("wall.json");
  spit(scene, wall_scene_json());
  // One move in the first frame, then 4 s of frames without moves: the
  // hidden sphere's TBV expires and renews along the way.
  std::string frames_text;
  for (int i = 0; i < 120; ++i) {
    const double t = i / 30.0;
    frames_text += "{\"t\": " + std::to_string(t) +
                   ", \"eye\": [10, 10, 1], \"dir\": [0, 0, 1], \"up\": [0, 1, 0], "
                   "\"fov_y_deg\": 60, \"aspect\": 1, \"near\": 0.05, \"far\": 1000" +
                   (i == 0 ? ", \"moves\": [{\"id\": 2, \"center\": [10, 10, 15]}]" : "") + "}\n";
  }
  const std::string frames = server.path("frames.jsonl");
  spit(frames, frames_text);
  server.extra_args() = {"--scene", "wall=" + scene};
  ASSERT_TRUE(server.start());
  const std::string replay_out = server.path("replay.jsonl"), view_out = server.path("view.jsonl");
  ProcessResult r = run_program({VOXVIS_CLI, "replay", "--scene", scene, "--frames", frames,
                                 "--out", replay_out, "-q"},
                                server.dir());
  ASSERT_EQ(r.status, 0) << r.err;
  ASSERT_NE(slurp(replay_out).find("\"tbvs_expired\":1"), std::string::npos)
      << "the walk should renew the TBV";
  r = run_program({VOXVIS_CLI, "view", "--server", server.address(), "--scene", "wall", "--frames",
                   frames, "--out", view_out, "-q"},
                  server.dir());
  ASSERT_EQ(r.status, 0) << r.err;
  expect_same_output(slurp(replay_out), slurp(view_out), "voxvis view");
}

TEST(ServerCli, LoadgenManyViewersOfOneScene) {
  const std::string examples = std::string(VOXVIS_SOURCE_DIR) + "/examples/paper";
  ServerProcess server;
  server.extra_args() = {"--scene", "paper=" + examples + "/scene.json"};
  ASSERT_TRUE(server.start());
  const std::string report = server.path("loadgen.json");
  const ProcessResult r =
      run_program({VOXVIS_CLI, "loadgen", "--server", server.address(), "--scene", "paper",
                   "--frames", examples + "/frames.jsonl", "--viewers", "6", "--rate", "120",
                   "--duration", "3", "--json", report, "-q"},
                  server.dir());
  ASSERT_EQ(r.status, 0) << r.err;
  const nlohmann::json j = nlohmann::json::parse(slurp(report), nullptr, false);
  ASSERT_FALSE(j.is_discarded());
  EXPECT_EQ(j.at("viewers"), 6);
  EXPECT_TRUE(j.at("errors").empty()) << j.dump();
  EXPECT_GT(j.at("frames").get<double>(), 6.0);
  v1::SceneInfo info;
  ASSERT_TRUE(server.api().stats("paper", &info).ok());
  EXPECT_GE(static_cast<double>(info.frames_served()), j.at("frames").get<double>());
  EXPECT_EQ(server.terminate(), 0);
}

}  // namespace
}  // namespace voxvis::servertest
