// The data directory: round trips, atomic overwrites, tolerance of damaged
// positions files, and refusal of directories that cannot be written.
#include <gtest/gtest.h>

#include <stdlib.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "store.h"

namespace voxvis::server {
namespace {
namespace fs = std::filesystem;

class StoreTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string templ = (fs::temp_directory_path() / "voxvis_store_XXXXXX").string();
    ASSERT_NE(::mkdtemp(templ.data()), nullptr);
    root_ = templ;
    dir_ = (root_ / "data").string();
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(root_, ec);
  }

  std::vector<std::string> scene_dir_listing() const {
    std::vector<std::string> names;
    for (const auto& e : fs::directory_iterator(fs::path(dir_) / "scenes")) {
      names.push_back(e.path().filename().string());
    }
    std::sort(names.begin(), names.end());
    return names;
  }
  static std::string read(const fs::path& p) {
    std::ifstream in(p);
    std::ostringstream s;
    s << in.rdbuf();
    return s.str();
  }
  static void write(const fs::path& p, const std::string& text) { std::ofstream(p) << text; }

  fs::path root_;
  std::string dir_;
  std::vector<std::string> warnings_;
  std::function<void(const std::string&)> warn_ = [this](const std::string& w) {
    warnings_.push_back(w);
  };
};

TEST(StoreIds, Valid) {
  EXPECT_TRUE(valid_scene_id("a"));
  EXPECT_TRUE(valid_scene_id("City_01.v2-final"));
  EXPECT_TRUE(valid_scene_id(std::string(64, 'x')));
  EXPECT_FALSE(valid_scene_id(""));
  EXPECT_FALSE(valid_scene_id(std::string(65, 'x')));
  EXPECT_FALSE(valid_scene_id(".hidden"));
  EXPECT_FALSE(valid_scene_id(".."));
  EXPECT_FALSE(valid_scene_id("a/b"));
  EXPECT_FALSE(valid_scene_id("a b"));
  EXPECT_FALSE(valid_scene_id("caf\xc3\xa9"));
}

TEST_F(StoreTest, OpenCreatesDirectories) {
  SceneStore store;
  const Status s = store.open(dir_);
  ASSERT_TRUE(s.ok) << s.str();
  EXPECT_TRUE(fs::is_directory(fs::path(dir_) / "scenes"));
  EXPECT_EQ(store.dir(), dir_);
  EXPECT_TRUE(store.load_all(warn_).empty());
  EXPECT_TRUE(scene_dir_listing().empty()) << "the writability probe must be removed";
}

TEST_F(StoreTest, SceneAndPositionsRoundTrip) {
  SceneStore store;
  ASSERT_TRUE(store.open(dir_).ok);
  ASSERT_TRUE(store.save_scene("b", "{\"scene\": \"b\"}").ok);
  ASSERT_TRUE(store.save_scene("a", "{\"scene\": \"a\"}\n").ok);
  const double t = 0.1 + 0.2;  // 0.30000000000000004: needs all 17 digits
  const std::vector<Move> moves = {
      {7, {0.1 + 0.2, -1e-300, 123456789.123456789}},
      {4294967295u, {1.0 / 3.0, 2.0 / 3.0, -0.0}},
  };
  ASSERT_TRUE(store.save_positions("a", t, moves).ok);

  SceneStore reopened;
  ASSERT_TRUE(reopened.open(dir_).ok);
  const std::vector<StoredScene> scenes = reopened.load_all(warn_);
  EXPECT_TRUE(warnings_.empty());
  ASSERT_EQ(scenes.size(), 2u);
  EXPECT_EQ(scenes[0].id, "a");
  EXPECT_EQ(scenes[0].json, "{\"scene\": \"a\"}\n");
  EXPECT_EQ(scenes[0].json_path, (fs::path(dir_) / "scenes" / "a.json").string());
  ASSERT_TRUE(scenes[0].t.has_value());
  EXPECT_EQ(*scenes[0].t, t);  // exact, not near
  EXPECT_NE(*scenes[0].t, 0.3);
  ASSERT_EQ(scenes[0].positions.size(), moves.size());
  for (std::size_t i = 0; i < moves.size(); ++i) {
    EXPECT_EQ(scenes[0].positions[i].id, moves[i].id);
    for (int axis = 0; axis < 3; ++axis) {
      EXPECT_EQ(scenes[0].positions[i].center[axis], moves[i].center[axis]) << i << " " << axis;
    }
  }
  EXPECT_EQ(scenes[1].id, "b");
  EXPECT_FALSE(scenes[1].t.has_value());
  EXPECT_TRUE(scenes[1].positions.empty());

  const nlohmann::json doc = nlohmann::json::parse(read(fs::path(dir_) / "scenes" / "a.positions"));
  EXPECT_EQ(doc["format"], "voxvis-positions/1");
  EXPECT_EQ(doc["moves"][0]["id"], 7);
}

TEST_F(StoreTest, OverwriteIsWholeAndLeavesNoTemporaries) {
  SceneStore store;
  ASSERT_TRUE(store.open(dir_).ok);
  ASSERT_TRUE(store.save_scene("s", std::string(100000, 'x')).ok);
  ASSERT_TRUE(store.save_scene("s", "short").ok);
  for (int i = 0; i < 5; ++i) {
    ASSERT_TRUE(store.save_positions("s", i, {{1, {double(i), 0, 0}}}).ok);
  }
  EXPECT_EQ(read(fs::path(dir_) / "scenes" / "s.json"), "short");
  EXPECT_EQ(scene_dir_listing(), (std::vector<std::string>{"s.json", "s.positions"}));
  const auto scenes = store.load_all(warn_);
  ASSERT_EQ(scenes.size(), 1u);
  EXPECT_EQ(scenes[0].t, 4.0);
  ASSERT_EQ(scenes[0].positions.size(), 1u);
  EXPECT_EQ(scenes[0].positions[0].center.x, 4.0);
}

TEST_F(StoreTest, OpenRemovesStrayTemporaries) {
  SceneStore store;
  ASSERT_TRUE(store.open(dir_).ok);
  ASSERT_TRUE(store.save_scene("keep", "{}").ok);
  // What a crash between create and rename leaves behind.
  write(fs::path(dir_) / "scenes" / ".tmp-keep.json.999.0", "{partial");
  write(fs::path(dir_) / "scenes" / ".tmp-keep.positions.999.1", "");
  SceneStore reopened;
  ASSERT_TRUE(reopened.open(dir_).ok);
  EXPECT_EQ(scene_dir_listing(), std::vector<std::string>{"keep.json"});
  EXPECT_EQ(reopened.load_all(warn_).size(), 1u);
}

TEST_F(StoreTest, BadPositionsAreIgnoredWithAWarning) {
  SceneStore store;
  ASSERT_TRUE(store.open(dir_).ok);
  const fs::path scenes = fs::path(dir_) / "scenes";
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"garbage", "not json at all {"},
      {"truncated", R"({"format": "voxvis-positions/1", "t": 1, "moves": [{"id": 1, "cen)"},
      {"format", R"({"format": "voxvis-positions/2", "t": 1, "moves": []})"},
      {"no_t", R"({"format": "voxvis-positions/1", "moves": []})"},
      {"bad_id", R"({"format": "voxvis-positions/1", "t": 1, "moves": [{"id": -1, "center": [0,0,0]}]})"},
      {"big_id", R"({"format": "voxvis-positions/1", "t": 1, "moves": [{"id": 4294967296, "center": [0,0,0]}]})"},
      {"short_center", R"({"format": "voxvis-positions/1", "t": 1, "moves": [{"id": 1, "center": [0,0]}]})"},
      {"string_coord", R"({"format": "voxvis-positions/1", "t": 1, "moves": [{"id": 1, "center": [0,"1",0]}]})"},
      {"array", "[]"},
  };
  for (const auto& [id, text] : cases) {
    ASSERT_TRUE(store.save_scene(id, "{}").ok);
    write(scenes / (id + ".positions"), text);
  }
  const auto loaded = store.load_all(warn_);
  ASSERT_EQ(loaded.size(), cases.size()) << "a bad positions file must not drop its scene";
  for (const StoredScene& s : loaded) {
    EXPECT_FALSE(s.t.has_value()) << s.id;
    EXPECT_TRUE(s.positions.empty()) << s.id;
  }
  ASSERT_EQ(warnings_.size(), cases.size());
  for (const auto& [id, text] : cases) {
    const std::string path = (scenes / (id + ".positions")).string();
    const bool named = std::any_of(warnings_.begin(), warnings_.end(), [&](const std::string& w) {
      return w.rfind(path + ": ", 0) == 0;
    });
    EXPECT_TRUE(named) << "no warning names " << path;
  }
  const auto has = [&](const std::string& needle) {
    return std::any_of(warnings_.begin(), warnings_.end(),
                       [&](const std::string& w) { return w.find(needle) != std::string::npos; });
  };
  EXPECT_TRUE(has("moves[0].center[1]"));
  EXPECT_TRUE(has("moves[0].id"));
}

TEST_F(StoreTest, InvalidIdsAreSkippedAndRefused) {
  SceneStore store;
  ASSERT_TRUE(store.open(dir_).ok);
  const fs::path scenes = fs::path(dir_) / "scenes";
  ASSERT_TRUE(store.save_scene("ok", "{}").ok);
  write(scenes / "bad id.json", "{}");
  write(scenes / (std::string(65, 'x') + ".json"), "{}");
  write(scenes / "notes.txt", "hello");
  write(scenes / "orphan.positions", R"({"format": "voxvis-positions/1", "t": 1, "moves": []})");
  fs::create_directory(scenes / "dir.json");
  const auto loaded = store.load_all(warn_);
  ASSERT_EQ(loaded.size(), 1u);
  EXPECT_EQ(loaded[0].id, "ok");

  for (const std::string id : {"", "../escape", ".hidden", "a/b"}) {
    EXPECT_FALSE(store.save_scene(id, "{}").ok) << id;
    EXPECT_FALSE(store.save_positions(id, 0, {}).ok) << id;
    EXPECT_FALSE(store.remove_scene(id).ok) << id;
  }
  EXPECT_FALSE(fs::exists(fs::path(dir_) / "escape.json"));
}

TEST_F(StoreTest, NonFinitePositionsAreRefused) {
  SceneStore store;
  ASSERT_TRUE(store.open(dir_).ok);
  const double inf = std::numeric_limits<double>::infinity();
  const Status s = store.save_positions("a", 1, {{1, {0, 0, 0}}, {2, {0, inf, 0}}});
  EXPECT_FALSE(s.ok);
  EXPECT_EQ(s.field, "positions[1].center");
  EXPECT_FALSE(store.save_positions("a", std::nan(""), {}).ok);
  EXPECT_FALSE(fs::exists(fs::path(dir_) / "scenes" / "a.positions"));
}

TEST_F(StoreTest, RemoveDeletesBothFilesAndToleratesMissing) {
  SceneStore store;
  ASSERT_TRUE(store.open(dir_).ok);
  ASSERT_TRUE(store.save_scene("x", "{}").ok);
  ASSERT_TRUE(store.save_positions("x", 1, {}).ok);
  ASSERT_TRUE(store.save_scene("y", "{}").ok);
  ASSERT_TRUE(store.remove_scene("x").ok);
  EXPECT_EQ(scene_dir_listing(), std::vector<std::string>{"y.json"});
  EXPECT_TRUE(store.remove_scene("x").ok);
  EXPECT_TRUE(store.remove_scene("never-existed").ok);
  ASSERT_TRUE(store.remove_scene("y").ok);  // no positions file
  EXPECT_TRUE(store.load_all(warn_).empty());
}

TEST_F(StoreTest, UnwritableDirectoryIsAnError) {
  // A path under a regular file cannot be created, even by root.
  write(root_ / "file", "x");
  SceneStore store;
  Status s = store.open((root_ / "file" / "sub").string());
  EXPECT_FALSE(s.ok);
  EXPECT_NE(s.str().find((root_ / "file" / "sub").string()), std::string::npos) << s.str();
  s = store.open((root_ / "file").string());
  EXPECT_FALSE(s.ok);
  EXPECT_EQ(s.field, (root_ / "file" / "scenes").string());
  EXPECT_TRUE(store.dir().empty()) << "a failed open must not leave a directory set";
}

TEST_F(StoreTest, ReadOnlyDirectoryIsAnError) {
  if (::geteuid() == 0) GTEST_SKIP() << "root ignores permission bits";
  SceneStore store;
  ASSERT_TRUE(store.open(dir_).ok);
  fs::permissions(fs::path(dir_) / "scenes", fs::perms::owner_read | fs::perms::owner_exec);
  SceneStore readonly;
  const Status s = readonly.open(dir_);
  fs::permissions(fs::path(dir_) / "scenes", fs::perms::owner_all);
  EXPECT_FALSE(s.ok);
  EXPECT_EQ(s.field, (fs::path(dir_) / "scenes").string());
  EXPECT_NE(s.message.find("not writable"), std::string::npos) << s.str();
}

}  // namespace
}  // namespace voxvis::server
