// examples/python/tick_client.py against the real server: its lines equal
// those of `voxvis replay` and `voxvis tick` (apart from the stats' times)
// in both encodings, with one viewer on a moving scene and three on a static
// one, and over TLS; and its failures are one clear line and exit status 2,
// never a traceback. Runs Debian's python3 (VOXVIS_PYTHON) with the stubs
// the build generates (VOXVIS_PYTHON_STUBS).
#include <algorithm>
#include <filesystem>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "server_process.h"
#include "voxvis/format.h"

namespace voxvis::servertest {
namespace {

const std::string kSimulation = "simulation-token-0123456789";
const std::string kViewer = "viewer-token-0123456789";

/// Runs tick_client.py with `args`; `env` ("NAME=value") added to its environment.
ProcessResult run_python(const ServerProcess& server, const std::vector<std::string>& args,
                         const std::vector<std::string>& env = {}) {
  std::vector<std::string> argv = {"/usr/bin/env", "-u", "VOXVIS_TOKEN_FILE", "PYTHONDONTWRITEBYTECODE=1",
                                   std::string("PYTHONPATH=") + VOXVIS_PYTHON_STUBS};
  argv.insert(argv.end(), env.begin(), env.end());
  argv.push_back(VOXVIS_PYTHON);
  argv.push_back(std::string(VOXVIS_SOURCE_DIR) + "/examples/python/tick_client.py");
  argv.insert(argv.end(), {"--server", server.address()});
  argv.insert(argv.end(), args.begin(), args.end());
  return run_program(argv, server.dir());
}

/// Fails the test, with a clear message, when Debian's python3 cannot import
/// gRPC and protobuf (deploy/deps.sh installs python3-grpcio and python3-protobuf).
::testing::AssertionResult python_ready(const ServerProcess& server) {
  const ProcessResult r =
      run_program({VOXVIS_PYTHON, "-c", "import grpc, google.protobuf"}, server.dir());
  if (r.status == 0) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << VOXVIS_PYTHON << " cannot import grpc and google.protobuf: install the "
                                          "Debian packages python3-grpcio and python3-protobuf (deploy/deps.sh)\n"
                                       << r.err;
}

/// An output line with its times (time_us and its split) replaced by "T".
std::string without_times(std::string line) {
  for (const std::string key : {"\"time_us\":", "\"traverse_us\":", "\"render_us\":", "\"retest_us\":"}) {
    const std::size_t at = line.find(key);
    if (at == std::string::npos) continue;
    const std::size_t begin = at + key.size();
    const std::size_t end = line.find_first_not_of("-0123456789.", begin);
    if (end == std::string::npos) continue;
    line = line.substr(0, begin) + "T" + line.substr(end);
  }
  return line;
}

/// Two output files agree byte for byte but for the times.
void expect_same_lines(const std::string& expected_path, const std::string& actual_path) {
  const std::vector<std::string> expected = lines_of(slurp(expected_path));
  const std::vector<std::string> actual = lines_of(slurp(actual_path));
  ASSERT_FALSE(expected.empty()) << expected_path;
  ASSERT_EQ(actual.size(), expected.size()) << actual_path << " against " << expected_path;
  for (std::size_t i = 0; i < expected.size(); ++i) {
    const std::string e = without_times(expected[i]), a = without_times(actual[i]);
    ASSERT_NE(e.find("\"time_us\":T"), std::string::npos) << e;
    ASSERT_EQ(a, e) << actual_path << " line " << i + 1 << " differs from " << expected_path;
  }
}

/// The first `count` lines of the bundled walkthrough, and the same without
/// moves; the bundled scene, and the same with every object static.
struct Recording {
  std::string frames, still_frames, static_scene;
};

Recording write_recording(const ServerProcess& server, std::size_t count) {
  const std::string examples = std::string(VOXVIS_SOURCE_DIR) + "/examples/paper";
  Recording rec{server.path("frames.jsonl"), server.path("still.jsonl"), server.path("static.json")};
  const std::vector<std::string> lines = lines_of(slurp(examples + "/frames.jsonl"));
  std::string frames, still;
  for (std::size_t i = 0; i < count && i < lines.size(); ++i) {
    FrameInput frame;
    FormatError error;
    EXPECT_TRUE(parse_frame_line(lines[i], "frames.jsonl", static_cast<int>(i + 1), &frame, &error)) << error.str();
    EXPECT_FALSE(frame.moves.empty());
    frames += lines[i] + "\n";
    frame.moves.clear();
    still += frame_to_json(frame) + "\n";
  }
  spit(rec.frames, frames);
  spit(rec.still_frames, still);
  SceneDesc scene;
  FormatError error;
  EXPECT_TRUE(parse_scene(slurp(examples + "/scene.json"), "scene.json", &scene, &error)) << error.str();
  for (ObjectDesc& o : scene.objects) {
    o.dynamic = false;
    o.max_speed = 0.0;
  }
  spit(rec.static_scene, scene_to_json(scene));
  return rec;
}

TEST(PythonExample, TickClientWritesWhatTheCliWrites) {
  ServerProcess server;
  ASSERT_TRUE(python_ready(server));
  const Recording rec = write_recording(server, 20);
  const std::string paper = std::string(VOXVIS_SOURCE_DIR) + "/examples/paper/scene.json";
  const std::string sim_token = server.path("sim.token"), viewer_token = server.path("viewer.token");
  spit(sim_token, kSimulation + "\n");
  spit(viewer_token, "# the viewer role is enough without moves\n" + kViewer + "\n");
  spit(server.path("tokens"), "simulation " + kSimulation + "\nviewer " + kViewer + "\n");
  server.extra_args() = {"--tokens", server.path("tokens"), "--scene", "moving=" + paper, "--scene",
                         "moving_delta=" + paper};
  for (const char* id : {"still_cli", "still", "still_delta"})
    server.extra_args().insert(server.extra_args().end(), {"--scene", std::string(id) + "=" + rec.static_scene});
  ASSERT_TRUE(server.start());

  // One viewer, with the recording's moves: replay's lines, in both encodings.
  const std::string replay = server.path("replay.jsonl");
  ProcessResult r = run_program(
      {VOXVIS_CLI, "replay", "--scene", paper, "--frames", rec.frames, "--out", replay, "-q"}, server.dir());
  ASSERT_EQ(r.status, 0) << r.err;
  r = run_python(server, {"--scene", "moving", "--frames", rec.frames, "--out", server.path("py.jsonl"),
                          "--token-file", sim_token});
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.err.find("20 ticks of 1 viewers"), std::string::npos) << r.err;
  // The server sent id sets in both forms (the smaller one each time).
  EXPECT_GT(number_before(r.err, " as gaps"), 0) << r.err;
  EXPECT_GT(number_before(r.err, " as bitsets"), 0) << r.err;
  expect_same_lines(replay, server.path("py.jsonl"));
  r = run_python(server, {"--scene", "moving_delta", "--frames", rec.frames, "--out", server.path("py_delta.jsonl"),
                          "--delta", "-q"},
                 {"VOXVIS_TOKEN_FILE=" + sim_token});
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(r.err, "");
  expect_same_lines(replay, server.path("py_delta.jsonl"));

  // Three viewers, each from its own start in the recording: `voxvis tick`'s
  // files (a static scene, so that the viewers' frames, run in parallel, do
  // not depend on each other's order); viewer 0's also equal replay's.
  const std::string cli = server.path("cli"), still_replay = server.path("still_replay.jsonl");
  r = run_program({VOXVIS_CLI, "tick", "--server", server.address(), "--token-file", viewer_token, "--scene",
                   "still_cli", "--frames", rec.still_frames, "--viewers", "3", "--out", cli, "-q"},
                  server.dir());
  ASSERT_EQ(r.status, 0) << r.err;
  r = run_program({VOXVIS_CLI, "replay", "--scene", rec.static_scene, "--frames", rec.still_frames, "--out",
                   still_replay, "-q"},
                  server.dir());
  ASSERT_EQ(r.status, 0) << r.err;
  expect_same_lines(still_replay, cli + "/viewer-0.jsonl");
  for (const char* mode : {"full", "delta"}) {
    SCOPED_TRACE(mode);
    const bool delta = std::string(mode) == "delta";
    const std::string out = server.path(std::string("py_") + mode);
    std::vector<std::string> args = {"--scene",   delta ? "still_delta" : "still", "--frames", rec.still_frames,
                                     "--viewers", "3",                             "--out",    out};
    if (delta) args.push_back("--delta");
    r = run_python(server, args, {"VOXVIS_TOKEN_FILE=" + viewer_token});
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_NE(r.err.find("20 ticks of 3 viewers"), std::string::npos) << r.err;
    for (int v = 0; v < 3; ++v) {
      SCOPED_TRACE("viewer " + std::to_string(v));
      const std::string name = "/viewer-" + std::to_string(v) + ".jsonl";
      expect_same_lines(cli + name, out + name);
    }
  }
  // The viewers walk from different lines: their files differ.
  EXPECT_NE(slurp(cli + "/viewer-0.jsonl"), slurp(cli + "/viewer-1.jsonl"));
  EXPECT_EQ(server.terminate(), 0);
}

TEST(PythonExample, TickClientFailsWithOneClearLine) {
  ServerProcess server;
  ASSERT_TRUE(python_ready(server));
  const std::string scene = server.path("wall.json"), frames = server.path("frames.jsonl");
  spit(scene, wall_scene_json());
  const auto line = [](double t, double fov, bool move) {
    return "{\"t\": " + std::to_string(t) + ", \"eye\": [10, 10, 1], \"dir\": [0, 0, 1], \"up\": [0, 1, 0], " +
           "\"fov_y_deg\": " + std::to_string(fov) + ", \"aspect\": 1, \"near\": 0.05, \"far\": 1000" +
           (move ? ", \"moves\": [{\"id\": 2, \"center\": [10, 10, 15]}]" : "") + "}\n";
  };
  const std::string viewer_token = server.path("viewer.token");
  spit(viewer_token, kViewer + "\n");
  spit(server.path("tokens"), "viewer " + kViewer + "\n");
  server.extra_args() = {"--tokens", server.path("tokens"), "--scene", "wall=" + scene};
  ASSERT_TRUE(server.start());
  const std::vector<std::string> viewer = {"--token-file", viewer_token};

  struct Case {
    std::string what, frames_text;
    std::vector<std::string> args;
    std::vector<std::string> expected;  // Substrings of the one line on stderr.
  };
  const std::vector<Case> cases = {
      {"unknown scene", line(0, 60, false), {"--scene", "nowhere", "--token-file", viewer_token},
       {"server: NOT_FOUND:", "nowhere"}},
      {"no token", line(0, 60, false), {"--scene", "wall"}, {"server: UNAUTHENTICATED:"}},
      {"moves with a viewer token", line(0, 60, true), {"--scene", "wall", "--token-file", viewer_token},
       {"server: PERMISSION_DENIED:"}},
      {"a camera the server refuses", line(0, 60, false) + "\n" + line(0.1, 190, false),
       {"--scene", "wall", "--token-file", viewer_token},
       {frames + ":3: viewers[0].camera.fov_y_deg: ", "190", "(viewer 0)"}},
      {"time going back", line(0.5, 60, false) + line(0.2, 60, false),
       {"--scene", "wall", "--token-file", viewer_token},
       {frames + ":2: server: INVALID_ARGUMENT: ", "[field t]"}},
      {"a region the server refuses",
       line(0, 60, false).substr(0, line(0, 60, false).size() - 2) + ", \"horizon_s\": -1}\n",
       {"--scene", "wall", "--token-file", viewer_token},
       {frames + ":1: viewers[0].camera.horizon_s: ", "(viewer 0)"}},
      {"a frames line without eye", line(0, 60, false) + "{\"t\": 1}\n",
       {"--scene", "wall", "--token-file", viewer_token},
       {frames + ":2: missing key 'eye'"}},
      {"no server", line(0, 60, false), {"--scene", "wall", "--server", "127.0.0.1:1"},
       {"cannot reach server at 127.0.0.1:1"}},
      {"several viewers without --out", line(0, 60, false), {"--viewers", "2", "--scene", "wall"}, {"--out"}},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.what);
    spit(frames, c.frames_text);
    std::vector<std::string> args = {"--frames", frames};
    args.insert(args.end(), c.args.begin(), c.args.end());
    const ProcessResult r = run_python(server, args);
    EXPECT_EQ(r.status, 2) << r.err;
    for (const std::string& e : c.expected) EXPECT_NE(r.err.find(e), std::string::npos) << e << "\n" << r.err;
    EXPECT_EQ(r.err.find("Traceback"), std::string::npos) << r.err;
    // One line; argparse's refusals come after its usage lines.
    if (c.args.front() != "--viewers") {
      EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    }
  }
  EXPECT_EQ(server.terminate(), 0);
}

TEST(PythonExample, TickClientOverTls) {
  ServerProcess server;
  ASSERT_TRUE(python_ready(server));
  const std::string cert = server.path("cert.pem"), key = server.path("key.pem");
  ASSERT_TRUE(make_test_certificate(cert, key, server.dir()));
  const std::string scene = server.path("wall.json"), frames = server.path("frames.jsonl");
  spit(scene, wall_scene_json());
  std::string text;
  for (int i = 0; i < 10; ++i)
    text += "{\"t\": " + std::to_string(i / 30.0) + ", \"eye\": [10, 10, " + std::to_string(1 + i * 0.1) +
            "], \"dir\": [0, 0.1, 1], \"up\": [0, 1, 0], \"fov_y_deg\": 60, \"aspect\": 1, \"near\": 0.05, "
            "\"far\": 1000}\n";
  spit(frames, text);
  server.extra_args() = {"--tls-cert", cert, "--tls-key", key, "--scene", "wall=" + scene};
  ASSERT_TRUE(server.start());
  const std::string replay = server.path("replay.jsonl"), out = server.path("py.jsonl");
  ProcessResult r =
      run_program({VOXVIS_CLI, "replay", "--scene", scene, "--frames", frames, "--out", replay, "-q"}, server.dir());
  ASSERT_EQ(r.status, 0) << r.err;
  r = run_python(server, {"--scene", "wall", "--frames", frames, "--out", out, "--tls-ca", cert,
                          "--tls-server-name", "voxvis.test", "-q"});
  ASSERT_EQ(r.status, 0) << r.err;
  expect_same_lines(replay, out);
  // Without the CA (plaintext) the call fails, saying so in one line.
  r = run_python(server, {"--scene", "wall", "--frames", frames, "-q"});
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("cannot reach server at " + server.address()), std::string::npos) << r.err;
  EXPECT_EQ(server.terminate(), 0);
}

}  // namespace
}  // namespace voxvis::servertest
