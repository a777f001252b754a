// What the commands do with an output path that is not a regular file
// (client/output_file.h): a character device or a FIFO is written to in
// place, never replaced; a directory, a socket or a block device is refused
// naming what it is. Before, as root, `--scene-out /dev/null` renamed a
// temporary file over the device node and exited 0.
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <sys/un.h>
#include <unistd.h>

#include <filesystem>
#include <future>
#include <iterator>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "cli_runner.h"
#include "files.h"

namespace voxvis::test {
namespace {

using ::testing::HasSubstr;

class OutputFiles : public Cli {
 protected:
  void SetUp() override {
    Cli::SetUp();
    write_paper("s.json", "f.jsonl", 60, 5, 3);
  }
  mode_t type_of(const std::string& name) {
    struct stat st{};
    EXPECT_EQ(::lstat(path(name).c_str(), &st), 0) << name;
    return st.st_mode & S_IFMT;
  }
  /// Whether this process may make device nodes (root, with CAP_MKNOD).
  bool mknod_char(const std::string& name, unsigned major, unsigned minor) {
    return ::mknod(path(name).c_str(), S_IFCHR | 0666, makedev(major, minor)) == 0;
  }
};

TEST_F(OutputFiles, AFifoIsWrittenInPlace) {
  const std::string replayed = run({"replay", "--scene", path("s.json"), "--frames", path("f.jsonl")}).out;
  ASSERT_FALSE(replayed.empty());
  ASSERT_EQ(::mkfifo(path("out.fifo").c_str(), 0600), 0);
  std::future<std::string> read = std::async(std::launch::async, [this] { return slurp(path("out.fifo")); });
  const Result r = run({"replay", "--scene", path("s.json"), "--frames", path("f.jsonl"), "--out", path("out.fifo")});
  EXPECT_EQ(r.status, 0) << r.err;
  // The same answers (the frames' times aside).
  const auto answers = [](const std::string& text) {
    std::vector<std::string> out;
    for (const std::string& line : lines_of(text)) out.push_back(line.substr(0, line.find(",\"stats\"")));
    return out;
  };
  EXPECT_EQ(answers(read.get()), answers(replayed));
  EXPECT_EQ(type_of("out.fifo"), static_cast<mode_t>(S_IFIFO)) << "still a FIFO";
  EXPECT_EQ(files(), (std::vector<std::string>{"f.jsonl", "out.fifo", "s.json"})) << "no temporary file left";
}

// A link to a regular file stays a link: the file it names is replaced (as
// /dev/stdout redirected to a file writes that file). Before, the rename
// replaced the link itself.
TEST_F(OutputFiles, ALinkIsFollowedAndKept) {
  std::filesystem::create_directories(path("real"));
  spit(path("real/out.jsonl"), "old\n");
  std::filesystem::create_symlink(path("real/out.jsonl"), path("link.jsonl"));
  const Result r =
      run({"replay", "--scene", path("s.json"), "--frames", path("f.jsonl"), "--out", path("link.jsonl")});
  EXPECT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(type_of("link.jsonl"), static_cast<mode_t>(S_IFLNK)) << "the link was replaced";
  EXPECT_EQ(lines_of(slurp(path("real/out.jsonl"))).size(), 3u);
  EXPECT_EQ(std::distance(std::filesystem::directory_iterator(path("real")), std::filesystem::directory_iterator()), 1)
      << "no temporary file left beside it";
}

TEST_F(OutputFiles, DirectoriesAndSocketsAreRefusedNamingWhatTheyAre) {
  std::filesystem::create_directories(path("dir"));
  const int sock = ::socket(AF_UNIX, SOCK_STREAM, 0);
  ASSERT_GE(sock, 0);
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  const std::string sock_path = path("sock");
  ASSERT_LT(sock_path.size(), sizeof addr.sun_path);
  std::copy(sock_path.begin(), sock_path.end(), addr.sun_path);
  ASSERT_EQ(::bind(sock, reinterpret_cast<const sockaddr*>(&addr), sizeof addr), 0);
  for (const auto& [name, what] : {std::pair<std::string, std::string>{"dir", "is a directory"}, {"sock", "is a socket"}}) {
    const std::string out = path(name);
    const std::vector<std::vector<std::string>> commands = {
        {"replay", "--scene", path("s.json"), "--frames", path("f.jsonl"), "--out", out},
        {"generate", "--preset", "paper", "--objects", "50", "--dynamic", "5", "--scene-out", out, "--frames-out", path("g.jsonl")},
        {"export", "--scene", path("s.json"), "--vdb", out},
        {"verify", "--scene", path("s.json"), "--frames", path("f.jsonl"), "--reference", "raycast",
         "--resolution", "64x36", "--out", out}};
    for (const std::vector<std::string>& c : commands) {
      const Result r = run(c);
      EXPECT_EQ(r.status, 2) << c[0] << " " << name << ": " << r.err;
      EXPECT_THAT(r.err, HasSubstr("voxvis: error: " + out + ": " + what + ", not a file to write")) << c[0];
    }
  }
  ::close(sock);
  EXPECT_EQ(type_of("dir"), static_cast<mode_t>(S_IFDIR));
  EXPECT_EQ(type_of("sock"), static_cast<mode_t>(S_IFSOCK));
  EXPECT_FALSE(std::filesystem::exists(path("g.jsonl")));
}

TEST_F(OutputFiles, DeviceNodesAreWrittenThroughNeverReplaced) {
  if (!mknod_char("null", 1, 3)) GTEST_SKIP() << "cannot make device nodes here (not root): the FIFO test covers the path";
  ASSERT_TRUE(mknod_char("full", 1, 7));
  // Written through: the node stays a device, the run succeeds.
  const std::vector<std::vector<std::string>> to_null = {
      {"replay", "--scene", path("s.json"), "--frames", path("f.jsonl"), "--out", path("null")},
      {"generate", "--preset", "paper", "--objects", "50", "--dynamic", "5", "--scene-out", path("null"), "--frames-out", path("null")},
      {"export", "--scene", path("s.json"), "--vdb", path("null"), "-q"}};
  for (const std::vector<std::string>& c : to_null) {
    const Result r = run(c);
    EXPECT_EQ(r.status, 0) << c[0] << ": " << r.err;
    EXPECT_EQ(type_of("null"), static_cast<mode_t>(S_IFCHR)) << c[0] << " replaced the device node";
  }
  // A device that refuses the bytes (/dev/full): an error naming it.
  const Result r =
      run({"replay", "--scene", path("s.json"), "--frames", path("f.jsonl"), "--out", path("full")});
  EXPECT_EQ(r.status, 2) << r.err;
  EXPECT_THAT(r.err, HasSubstr("cannot write " + path("full") + ": No space left on device"));
  EXPECT_EQ(type_of("full"), static_cast<mode_t>(S_IFCHR));
  EXPECT_EQ(files(), (std::vector<std::string>{"f.jsonl", "full", "null", "s.json"})) << "no file made beside them";
}

}  // namespace
}  // namespace voxvis::test
