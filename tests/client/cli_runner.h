// cli_runner.h — runs the `voxvis` binary (VOXVIS_CLI) as a separate
// process in a temporary directory, capturing its exit status and output.
#pragma once

#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "files.h"
#include "voxvis/format.h"
#include "voxvis/generate.h"

extern char** environ;

namespace voxvis::test {

struct Result {
  int status = -1;      ///< Exit status; -1 when killed by a signal.
  int signal = 0;       ///< Signal that killed it, if any.
  std::string out, err;
  double seconds = 0.0;
};

class Cli : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string tmpl = (std::filesystem::temp_directory_path() / "voxvis-cli-XXXXXX").string();
    ASSERT_NE(::mkdtemp(tmpl.data()), nullptr);
    dir_ = tmpl;
  }
  void TearDown() override {
    std::error_code ec;
    std::filesystem::remove_all(dir_, ec);
  }

  std::string path(const std::string& name) const { return (dir_ / name).string(); }

  /// Writes a paper-like scene (voxvis generate's preset) and its
  /// walkthrough to `scene` and `frames` in the temporary directory.
  void write_paper(const std::string& scene, const std::string& frames, int objects, int dynamic,
                   int frame_count) {
    PaperSceneParams p;
    p.objects = objects;
    p.dynamic = dynamic;
    const SceneDesc desc = make_paper_scene(p);
    WalkthroughParams w;
    w.frames = frame_count;
    spit(path(scene), scene_to_json(desc));
    std::string text;
    for (const FrameInput& f : make_walkthrough(desc, w)) text += frame_to_json(f) + "\n";
    spit(path(frames), text);
  }

  /// Runs the CLI with `args`; stdout and stderr captured through files.
  /// `env` (NAME=value entries) is added to the environment.
  Result run(const std::vector<std::string>& args, const std::vector<std::string>& env = {}) {
    const std::string out = path(".stdout"), err = path(".stderr");
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, STDIN_FILENO, "/dev/null", O_RDONLY, 0);
    posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, out.c_str(),
                                     O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, err.c_str(),
                                     O_WRONLY | O_CREAT | O_TRUNC, 0644);
    std::vector<std::string> argv_s = {VOXVIS_CLI};
    argv_s.insert(argv_s.end(), args.begin(), args.end());
    std::vector<char*> argv;
    for (std::string& a : argv_s) argv.push_back(a.data());
    argv.push_back(nullptr);

    Result r;
    const auto start = std::chrono::steady_clock::now();
    pid_t pid = 0;
    std::vector<std::string> env_s(env);
    for (char** e = environ; *e != nullptr; ++e) env_s.emplace_back(*e);
    std::vector<char*> envp;
    for (std::string& e : env_s) envp.push_back(e.data());
    envp.push_back(nullptr);
    const int rc = posix_spawn(&pid, VOXVIS_CLI, &actions, nullptr, argv.data(), envp.data());
    posix_spawn_file_actions_destroy(&actions);
    EXPECT_EQ(rc, 0) << "cannot start " << VOXVIS_CLI;
    if (rc != 0) return r;
    int wstatus = 0;
    while (::waitpid(pid, &wstatus, 0) < 0) {
    }
    r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (WIFEXITED(wstatus)) r.status = WEXITSTATUS(wstatus);
    if (WIFSIGNALED(wstatus)) r.signal = WTERMSIG(wstatus);
    r.out = slurp(out);
    r.err = slurp(err);
    std::filesystem::remove(out);
    std::filesystem::remove(err);
    return r;
  }

  /// Files in the temporary directory (to check that no temp file is left).
  std::vector<std::string> files() const {
    std::vector<std::string> names;
    for (const auto& e : std::filesystem::directory_iterator(dir_)) names.push_back(e.path().filename().string());
    std::sort(names.begin(), names.end());
    return names;
  }

  std::filesystem::path dir_;
};

}  // namespace voxvis::test
