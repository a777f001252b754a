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

TEST(ServerCli, ViewMatchesReplay) {
  const std::string examples = std::string(VOXVIS_SOURCE_DIR) + "/examples/paper";
  ServerProcess server(replay_exact_args());
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

TEST(ServerCli, TickMatchesReplayForItsFirstViewer) {
  // `voxvis tick`: viewer 0 walks the recording as `replay` does (with its
  // moves, in both encodings); with three viewers each has its own file.
  const std::string examples = std::string(VOXVIS_SOURCE_DIR) + "/examples/paper";
  ServerProcess server(replay_exact_args());
  const std::vector<std::string> all_frames = lines_of(slurp(examples + "/frames.jsonl"));
  ASSERT_GE(all_frames.size(), 30u);
  std::string frames_text;
  for (std::size_t i = 0; i < 30; ++i) frames_text += all_frames[i] + "\n";
  const std::string frames = server.path("frames.jsonl");
  spit(frames, frames_text);
  server.extra_args() = {"--scene", "one=" + examples + "/scene.json", "--scene", "delta=" + examples + "/scene.json",
                         "--scene", "three=" + examples + "/scene.json"};
  ASSERT_TRUE(server.start());
  const std::string replay_out = server.path("replay.jsonl");
  ProcessResult r = run_program(
      {VOXVIS_CLI, "replay", "--scene", examples + "/scene.json", "--frames", frames, "--out", replay_out, "-q"},
      server.dir());
  ASSERT_EQ(r.status, 0) << r.err;
  const std::string expected = slurp(replay_out);

  const std::string one_out = server.path("tick.jsonl");
  r = run_program({VOXVIS_CLI, "tick", "--server", server.address(), "--scene", "one", "--frames", frames, "--out",
                   one_out, "-q"},
                  server.dir());
  ASSERT_EQ(r.status, 0) << r.err;
  expect_same_output(expected, slurp(one_out), "voxvis tick");
  const std::string delta_out = server.path("tick_delta.jsonl");
  r = run_program({VOXVIS_CLI, "tick", "--server", server.address(), "--scene", "delta", "--frames", frames,
                   "--out", delta_out, "-q", "--delta"},
                  server.dir());
  ASSERT_EQ(r.status, 0) << r.err;
  expect_same_output(expected, slurp(delta_out), "voxvis tick --delta");

  const std::string dir = server.path("three");
  r = run_program({VOXVIS_CLI, "tick", "--server", server.address(), "--scene", "three", "--frames", frames,
                   "--viewers", "3", "--out", dir},
                  server.dir());
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.err.find("30 ticks of 3 viewers"), std::string::npos) << r.err;
  for (int v = 0; v < 3; ++v) {
    const std::string text = slurp(dir + "/viewer-" + std::to_string(v) + ".jsonl");
    EXPECT_EQ(lines_of(text).size(), 30u) << "viewer " << v;
  }
  v1::SceneInfo info;
  ASSERT_TRUE(server.api().stats("three", &info).ok());
  EXPECT_EQ(info.frames_served(), 90u);
  EXPECT_EQ(info.moves_applied(), 30u * 200u);

  // Arguments it refuses, naming them.
  r = run_program({VOXVIS_CLI, "tick", "--server", server.address(), "--scene", "one", "--frames", frames,
                   "--viewers", "2"},
                  server.dir());
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("--out"), std::string::npos) << r.err;
  r = run_program({VOXVIS_CLI, "tick", "--server", server.address(), "--scene", "one", "--frames", frames,
                   "--viewers", "0", "--out", dir},
                  server.dir());
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("--viewers"), std::string::npos) << r.err;
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
  ServerProcess server(replay_exact_args());
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

// --occlusion-buffer applies to every scene the server builds: one from
// --scene, one created through the API, and one loaded again from the data
// directory at the next start. Each answers over the socket what `voxvis
// replay --occlusion-buffer 64` computes, which is not what the engine
// computes without the buffer (0) nor with the default width (160).
TEST(ServerCli, OcclusionBufferMatchesReplayForEveryScene) {
  const std::string examples = std::string(VOXVIS_SOURCE_DIR) + "/examples/paper";
  const std::vector<std::string> all_frames = lines_of(slurp(examples + "/frames.jsonl"));
  ASSERT_GE(all_frames.size(), 40u);
  std::string frames_text;
  for (std::size_t i = 0; i < 40; ++i) frames_text += all_frames[i] + "\n";
  ASSERT_NE(frames_text.find("\"moves\""), std::string::npos);
  ServerProcess server(replay_exact_args({"--occlusion-buffer", "64", "--scene", "paper_file=" + examples + "/scene.json"}));
  const std::string frames = server.path("frames.jsonl");
  spit(frames, frames_text);

  const auto replay = [&](const std::vector<std::string>& extra, const std::string& out) {
    std::vector<std::string> argv = {VOXVIS_CLI, "replay", "--scene", examples + "/scene.json",
                                     "--frames", frames, "--out", out, "-q"};
    argv.insert(argv.end(), extra.begin(), extra.end());
    const ProcessResult r = run_program(argv, server.dir());
    EXPECT_EQ(r.status, 0) << r.err;
    return slurp(out);
  };
  const std::string with_buffer = replay({"--occlusion-buffer", "64"}, server.path("on.jsonl"));
  const std::string without = replay({"--occlusion-buffer", "0"}, server.path("off.jsonl"));
  const std::string by_default = replay({}, server.path("default.jsonl"));
  const std::vector<std::string> on_lines = lines_of(with_buffer), off_lines = lines_of(without);
  const std::vector<std::string> default_lines = lines_of(by_default);
  ASSERT_EQ(on_lines.size(), 40u);
  ASSERT_EQ(off_lines.size(), 40u);
  ASSERT_EQ(default_lines.size(), 40u);
  // The buffer is on in replay's answers, and it changes them: the frames
  // whose PVS differ with and without it, and from the default width's.
  int differing = 0, differing_from_default = 0;
  for (std::size_t i = 0; i < on_lines.size(); ++i) {
    const nlohmann::json on = nlohmann::json::parse(on_lines[i], nullptr, false);
    const nlohmann::json off = nlohmann::json::parse(off_lines[i], nullptr, false);
    const nlohmann::json def = nlohmann::json::parse(default_lines[i], nullptr, false);
    ASSERT_FALSE(on.is_discarded() || off.is_discarded() || def.is_discarded()) << i;
    ASSERT_EQ(on.at("stats").value("ob_width", 0), 64) << on_lines[i];
    ASSERT_FALSE(off.at("stats").contains("ob_width")) << off_lines[i];
    ASSERT_EQ(def.at("stats").value("ob_width", 0), 160) << default_lines[i];
    if (on.at("pvs") != off.at("pvs")) ++differing;
    if (on.at("pvs") != def.at("pvs")) ++differing_from_default;
  }
  ASSERT_GT(differing, 0) << "the buffer changes no PVS on these frames: the test shows nothing";
  ASSERT_GT(differing_from_default, 0) << "64 and 160 pixels agree on every frame: the test shows nothing";
  // The wire carries the buffer's counters: the same lines to the byte
  // (time_us aside, which expect_same_output leaves out).
  const std::string& expected = with_buffer;

  ASSERT_TRUE(server.start());
  const std::string json = slurp(examples + "/scene.json");
  ASSERT_TRUE(server.api().create_scene_json("paper_api", json).ok());
  ASSERT_TRUE(server.api().create_scene_json("paper_kept", json).ok());
  const auto view = [&](const std::string& id) {
    const std::string out = server.path("view_" + id + ".jsonl");
    const ProcessResult r = run_program({VOXVIS_CLI, "view", "--server", server.address(), "--scene",
                                         id, "--frames", frames, "--out", out, "-q"},
                                        server.dir());
    EXPECT_EQ(r.status, 0) << r.err;
    return slurp(out);
  };
  expect_same_output(expected, view("paper_file"), "--scene, voxvis view");
  expect_same_output(expected, view("paper_api"), "CreateScene, voxvis view");
  ASSERT_EQ(server.terminate(), 0);

  // paper_kept was never moved: it comes back from the data directory as
  // it was created, and the buffer applies to it as well.
  ASSERT_TRUE(server.restart());
  std::vector<std::string> ids;
  ASSERT_TRUE(server.api().list_scenes(&ids).ok());
  ASSERT_EQ(ids, (std::vector<std::string>{"paper_api", "paper_file", "paper_kept"}));
  EXPECT_NE(server.log().find("loaded scene 'paper_kept' from the data directory"),
            std::string::npos)
      << server.log();
  expect_same_output(expected, view("paper_kept"), "data directory, voxvis view");
  EXPECT_EQ(server.terminate(), 0);
}

// A bad width is a start error naming the flag (exit status 2), found before
// the data directory is read: its scenes are neither loaded nor quarantined,
// and nothing listens.
TEST(ServerCli, BadOcclusionBufferIsAStartError) {
  ServerProcess server;
  ASSERT_TRUE(server.start());
  ASSERT_TRUE(server.api().create_scene_json("wall", wall_scene_json()).ok());
  ASSERT_EQ(server.terminate(), 0);

  for (const std::string bad : {"-1", "1", "7", "4097", "100000", "abc", "12.5", "64px"}) {
    SCOPED_TRACE("--occlusion-buffer " + bad);
    server.extra_args() = {"--occlusion-buffer", bad};
    const std::size_t log_before = server.log().size();
    EXPECT_FALSE(server.start());
    EXPECT_EQ(server.wait_exit(Seconds(10)), 2);
    const std::string log = server.log().substr(log_before);
    EXPECT_NE(log.find("error"), std::string::npos) << log;
    EXPECT_NE(log.find("--occlusion-buffer"), std::string::npos) << log;
    EXPECT_EQ(log.find("listening"), std::string::npos) << log;
    EXPECT_EQ(log.find("quarantine"), std::string::npos) << log;
    EXPECT_FALSE(fs::exists(server.path("port")));
  }
  // Out-of-range values are told the limits.
  const std::size_t log_before = server.log().size();
  server.extra_args() = {"--occlusion-buffer", "4097"};
  EXPECT_FALSE(server.start());
  EXPECT_NE(server.log().substr(log_before).find("from 8 to 4096, got 4097"), std::string::npos)
      << server.log();

  // The limits themselves are accepted, and the scene is still there.
  for (const std::string good : {"8", "4096", "0"}) {
    SCOPED_TRACE("--occlusion-buffer " + good);
    server.extra_args() = {"--occlusion-buffer", good};
    ASSERT_TRUE(server.start());
    std::vector<std::string> ids;
    ASSERT_TRUE(server.api().list_scenes(&ids).ok());
    EXPECT_EQ(ids, (std::vector<std::string>{"wall"}));
    v1::GetPvsResponse pvs;
    ASSERT_TRUE(server.api().get_pvs("wall", 0.0, wall_camera(), &pvs).ok());
    EXPECT_EQ(ids_of(pvs.pvs()), (std::vector<ObjectId>{1, 3}));
    EXPECT_EQ(server.terminate(), 0);
  }
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
  // Every stream was answered; a stream's first gap is its wait for the
  // first answer.
  EXPECT_EQ(j.at("streams_answered"), 6);
  EXPECT_GT(j.at("first_answer_max_ms").get<double>(), 0.0);
  EXPECT_GE(j.at("gap_max_ms").get<double>(), j.at("first_answer_max_ms").get<double>());
  v1::SceneInfo info;
  ASSERT_TRUE(server.api().stats("paper", &info).ok());
  EXPECT_GE(static_cast<double>(info.frames_served()), j.at("frames").get<double>());
  EXPECT_EQ(server.terminate(), 0);
}

TEST(ServerCli, LoadgenTicksReportAnswersAndTheServersCpu) {
  const std::string examples = std::string(VOXVIS_SOURCE_DIR) + "/examples/paper";
  ServerProcess server;
  server.extra_args() = {"--scene", "paper=" + examples + "/scene.json", "--metrics", "127.0.0.1:0"};
  ASSERT_TRUE(server.start());
  const std::string metrics = "127.0.0.1:" + std::to_string(server.metrics_port());
  const std::string report = server.path("ticks.json");
  const ProcessResult r =
      run_program({VOXVIS_CLI, "loadgen", "--server", server.address(), "--scene", "paper", "--tick",
                   "--frames", examples + "/frames.jsonl", "--viewers", "5", "--rate", "60", "--duration", "2",
                   "--delta", "--metrics", metrics, "--json", report, "-q"},
                  server.dir());
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.out.find("5 viewers a tick"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("server CPU"), std::string::npos) << r.out;
  const nlohmann::json j = nlohmann::json::parse(slurp(report), nullptr, false);
  ASSERT_FALSE(j.is_discarded());
  EXPECT_EQ(j.at("mode"), "tick");
  EXPECT_TRUE(j.at("errors").empty()) << j.dump();
  EXPECT_EQ(j.at("answer_errors"), 0);
  EXPECT_EQ(j.at("streams_answered"), 1);
  // Each tick answered answers all five viewers; sent ticks were answered or
  // shed by the server, never lost.
  const auto ticks = j.at("ticks_answered").get<std::uint64_t>();
  EXPECT_GT(ticks, 10u);
  EXPECT_EQ(j.at("frames").get<std::uint64_t>(), 5 * ticks);
  EXPECT_EQ(ticks + j.at("server_skipped").get<std::uint64_t>(), j.at("ticks_sent").get<std::uint64_t>());
  EXPECT_GT(j.at("answers_per_s").get<double>(), 0.0);
  // The server counted the same answers (it had no other client), and spent
  // CPU on them, part of it in the engine.
  EXPECT_EQ(j.at("server_answers").get<double>(), j.at("frames").get<double>());
  EXPECT_GT(j.at("server_cpu_s_per_answer").get<double>(), 0.0);
  EXPECT_GT(j.at("server_engine_s_per_answer").get<double>(), 0.0);
  EXPECT_NEAR(j.at("server_overhead_s_per_answer").get<double>(),
              j.at("server_cpu_s_per_answer").get<double>() - j.at("server_engine_s_per_answer").get<double>(),
              1e-12);

  // What it read: the process's CPU, and the engine's CPU in the scene's frames.
  const std::string text = http_get(server.metrics_port(), "/metrics");
  EXPECT_NE(text.find("\nprocess_cpu_seconds_total "), std::string::npos) << text;
  EXPECT_NE(text.find("\nvoxvis_frame_engine_cpu_seconds_total{scene=\"paper\"} "), std::string::npos) << text;

  // Bad arguments fail before the run, naming the flag.
  const ProcessResult many = run_program({VOXVIS_CLI, "loadgen", "--server", server.address(), "--scene", "paper",
                                          "--tick", "--viewers", "1025", "--rate", "30", "--duration", "1"},
                                         server.dir());
  EXPECT_EQ(many.status, 2);
  EXPECT_NE(many.err.find("--viewers: with --tick, at most 1024"), std::string::npos) << many.err;
  const ProcessResult no_metrics =
      run_program({VOXVIS_CLI, "loadgen", "--server", server.address(), "--scene", "paper", "--tick", "--viewers",
                   "2", "--rate", "30", "--duration", "1", "--metrics", server.address()},
                  server.dir());
  EXPECT_EQ(no_metrics.status, 2);
  EXPECT_NE(no_metrics.err.find("--metrics"), std::string::npos) << no_metrics.err;
  EXPECT_EQ(server.terminate(), 0);
}

}  // namespace
}  // namespace voxvis::servertest
