// Region cameras on the wire (Camera.eye_extent, omnidirectional,
// horizon_s): `voxvis view` and `voxvis tick` with the region flags, and
// the Python example with the fields in its frames file, answer what
// `voxvis replay` answers with the same region, on the arena with its
// players moving; a bad field is refused naming it.
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "server_process.h"
#include "voxvis/format.h"

namespace voxvis::servertest {
namespace {

TEST(ServerRegions, ViewTickAndPythonAnswerAsReplay) {
  ServerProcess server(replay_exact_args());
  const std::string scene = server.path("arena.json"), frames = server.path("arena.jsonl");
  ProcessResult r = run_program({VOXVIS_CLI, "generate", "--preset", "arena", "--size", "2", "--dynamic", "8",
                                 "--frames", "24", "--scene-out", scene, "--frames-out", frames},
                                server.dir());
  ASSERT_EQ(r.status, 0) << r.err;
  server.extra_args() = {"--scene", "view=" + scene, "--scene", "tick=" + scene, "--scene", "python=" + scene};
  ASSERT_TRUE(server.start());
  const std::vector<std::string> region = {"--eye-extent", "24,8,24", "--omnidirectional", "--horizon", "0.1"};

  const std::string replay_out = server.path("replay.jsonl");
  std::vector<std::string> args = {VOXVIS_CLI, "replay", "--scene", scene, "--frames", frames, "--out", replay_out,
                                   "-q"};
  args.insert(args.end(), region.begin(), region.end());
  r = run_program(args, server.dir());
  ASSERT_EQ(r.status, 0) << r.err;
  const std::string expected = slurp(replay_out);
  EXPECT_NE(expected.find("\"region\":true"), std::string::npos);

  for (const char* cmd : {"view", "tick"}) {
    SCOPED_TRACE(cmd);
    const std::string out = server.path(std::string(cmd) + ".jsonl");
    args = {VOXVIS_CLI, cmd, "--server", server.address(), "--scene", cmd, "--frames", frames, "--out", out, "-q"};
    args.insert(args.end(), region.begin(), region.end());
    r = run_program(args, server.dir());
    ASSERT_EQ(r.status, 0) << r.err;
    expect_same_output(expected, slurp(out), cmd);
  }

  // The Python example reads the region from the frames file's fields.
  std::string with_fields;
  for (const std::string& line : lines_of(slurp(frames))) {
    FrameInput f;
    FormatError error;
    ASSERT_TRUE(parse_frame_line(line, frames, 1, &f, &error)) << error.str();
    f.camera.eye_extent = Vec3(24.0, 8.0, 24.0);
    f.camera.omnidirectional = true;
    f.camera.horizon_s = 0.1;
    with_fields += frame_to_json(f) + "\n";
  }
  const std::string region_frames = server.path("region.jsonl"), py_out = server.path("python.jsonl");
  spit(region_frames, with_fields);
  r = run_program({"/usr/bin/env", "-u", "VOXVIS_TOKEN_FILE", "PYTHONDONTWRITEBYTECODE=1",
                   std::string("PYTHONPATH=") + VOXVIS_PYTHON_STUBS, VOXVIS_PYTHON,
                   std::string(VOXVIS_SOURCE_DIR) + "/examples/python/tick_client.py", "--server", server.address(),
                   "--scene", "python", "--frames", region_frames, "--out", py_out, "-q"},
                  server.dir());
  ASSERT_EQ(r.status, 0) << r.err;
  expect_same_output(expected, slurp(py_out), "tick_client.py");

  // A bad region is refused, naming the field; a bad flag before any call.
  args = {VOXVIS_CLI, "view", "--server", server.address(), "--scene", "view", "--frames", frames, "--horizon", "-1"};
  r = run_program(args, server.dir());
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("--horizon: must be in [0, 1e+09] seconds"), std::string::npos) << r.err;
  args = {VOXVIS_CLI, "tick", "--server", server.address(), "--scene", "tick", "--frames", frames, "--eye-extent",
          "1,2"};
  r = run_program(args, server.dir());
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("--eye-extent: expected H or HX,HY,HZ"), std::string::npos) << r.err;
  EXPECT_EQ(server.terminate(), 0);
}

}  // namespace
}  // namespace voxvis::servertest
