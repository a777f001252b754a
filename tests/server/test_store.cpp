// The data directory: round trips, atomic overwrites, quarantine of whatever
// cannot be loaded (damaged or out-of-range positions, stray entries,
// symlinks, which are never followed), and refusal of directories that cannot
// be written.
#include <gtest/gtest.h>

#include <stdlib.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "scenes/store.h"
#include "wire/calls.h"

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

  static std::vector<std::string> listing(const fs::path& dir) {
    std::vector<std::string> names;
    std::error_code ec;
    for (const auto& e : fs::directory_iterator(dir, ec)) {
      names.push_back(e.path().filename().string());
    }
    std::sort(names.begin(), names.end());
    return names;
  }
  std::vector<std::string> scene_dir_listing() const { return listing(fs::path(dir_) / "scenes"); }
  std::vector<std::string> quarantine_listing() const {
    return listing(fs::path(dir_) / "quarantine");
  }
  /// The one warning that starts with `path` + ": ", or "" (and the test fails).
  std::string warning_about(const fs::path& path) const {
    std::vector<std::string> found;
    for (const std::string& w : warnings_) {
      if (w.rfind(path.string() + ": ", 0) == 0) found.push_back(w);
    }
    EXPECT_EQ(found.size(), 1u) << "warnings naming " << path;
    return found.empty() ? "" : found[0];
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
      // A mesh's rotation as given: a norm a little off 1, digits to keep.
      {9, {1, 2, 3}, true, Quat(0.1 + 0.2, 1.0 / 3.0, -0.0, std::sqrt(1.0 - (0.1 + 0.2) * (0.1 + 0.2) - 1.0 / 9.0) * (1.0 + 5e-7))},
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
    EXPECT_EQ(scenes[0].positions[i].has_rotation, moves[i].has_rotation) << i;
    const Quat& got = scenes[0].positions[i].rotation;
    const Quat& want = moves[i].rotation;
    EXPECT_EQ(std::memcmp(&got, &want, sizeof got), 0) << i << ": every bit, the sign of zero too";
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
      // Finite but beyond the engine's clock (±kMaxSceneTime) or space (±kMaxCoordinate).
      {"huge_t", R"({"format": "voxvis-positions/1", "t": 1e300, "moves": []})"},
      {"early_t", R"({"format": "voxvis-positions/1", "t": -2e10, "moves": []})"},
      {"far_center", R"({"format": "voxvis-positions/1", "t": 1, "moves": [{"id": 1, "center": [0,0,-1e13]}]})"},
      // A mesh's rotation: four numbers of unit norm (within 1e-6).
      {"short_rotation", R"({"format": "voxvis-positions/1", "t": 1, "moves": [{"id": 1, "center": [0,0,0], "rotation": [1,0,0]}]})"},
      {"string_rotation", R"({"format": "voxvis-positions/1", "t": 1, "moves": [{"id": 1, "center": [0,0,0], "rotation": [1,0,"0",0]}]})"},
      {"long_rotation", R"({"format": "voxvis-positions/1", "t": 1, "moves": [{"id": 1, "center": [0,0,0], "rotation": [2,0,0,0]}]})"},
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
  EXPECT_TRUE(has("moves[0].center[2]"));
  EXPECT_TRUE(has("moves[0].id"));
  EXPECT_TRUE(has("t: expected a finite number of seconds within"));
  EXPECT_TRUE(has("moves[0].rotation: expected [w, x, y, z]"));
  EXPECT_TRUE(has("moves[0].rotation[2]: expected a number"));
  EXPECT_TRUE(has("moves[0].rotation: must be a unit quaternion [w, x, y, z] (norm within 1e-06 of 1), got norm 2"));

  // Each positions file is in quarantine/, its content kept; the scenes stay.
  std::vector<std::string> quarantined, kept;
  for (const auto& [id, text] : cases) {
    quarantined.push_back(id + ".positions");
    kept.push_back(id + ".json");
    EXPECT_EQ(read(fs::path(dir_) / "quarantine" / (id + ".positions")), text) << id;
    const std::string moved = (fs::path(dir_) / "quarantine" / (id + ".positions")).string();
    EXPECT_NE(warning_about(scenes / (id + ".positions")).find("moved to " + moved), std::string::npos);
  }
  std::sort(quarantined.begin(), quarantined.end());
  std::sort(kept.begin(), kept.end());
  EXPECT_EQ(quarantine_listing(), quarantined);
  EXPECT_EQ(scene_dir_listing(), kept);
  warnings_.clear();
  EXPECT_EQ(store.load_all(warn_).size(), cases.size());
  EXPECT_EQ(warnings_, std::vector<std::string>{}) << "quarantined once, then gone";
}

TEST_F(StoreTest, GoodPositionsAtTheLimitsLoad) {
  SceneStore store;
  ASSERT_TRUE(store.open(dir_).ok);
  ASSERT_TRUE(store.save_scene("a", "{}").ok);
  ASSERT_TRUE(store.save_positions("a", -kMaxSceneTime, {{1, {kMaxCoordinate, -kMaxCoordinate, 0}}}).ok);
  const auto loaded = store.load_all(warn_);
  EXPECT_TRUE(warnings_.empty());
  ASSERT_EQ(loaded.size(), 1u);
  EXPECT_EQ(loaded[0].t, -kMaxSceneTime);
  ASSERT_EQ(loaded[0].positions.size(), 1u);
  EXPECT_EQ(loaded[0].positions[0].center.x, kMaxCoordinate);
  EXPECT_FALSE(fs::exists(fs::path(dir_) / "quarantine"));
}

TEST_F(StoreTest, StrayEntriesAreQuarantinedAndInvalidIdsRefused) {
  SceneStore store;
  ASSERT_TRUE(store.open(dir_).ok);
  const fs::path scenes = fs::path(dir_) / "scenes";
  ASSERT_TRUE(store.save_scene("ok", "{}").ok);
  const std::string long_name = std::string(65, 'x') + ".json";
  write(scenes / "bad id.json", "{}");
  write(scenes / long_name, "{}");
  write(scenes / "notes.txt", "hello");
  write(scenes / "orphan.positions", R"({"format": "voxvis-positions/1", "t": 1, "moves": []})");
  fs::create_directory(scenes / "dir.json");
  write(scenes / "dir.json" / "inside", "x");
  fs::create_directory(scenes / ".tmp-dir");  // named like a temporary, but not one
  ASSERT_EQ(::mkfifo((scenes / "pipe.json").c_str(), 0600), 0);  // must not block the load
  const auto loaded = store.load_all(warn_);
  ASSERT_EQ(loaded.size(), 1u);
  EXPECT_EQ(loaded[0].id, "ok");
  EXPECT_EQ(scene_dir_listing(), std::vector<std::string>{"ok.json"});
  const std::vector<std::string> stray = {".tmp-dir", "bad id.json", "dir.json",        long_name,
                                          "notes.txt", "orphan.positions", "pipe.json"};
  std::vector<std::string> sorted = stray;
  std::sort(sorted.begin(), sorted.end());
  EXPECT_EQ(quarantine_listing(), sorted);
  EXPECT_EQ(warnings_.size(), stray.size());
  for (const std::string& name : stray) {
    EXPECT_NE(warning_about(scenes / name).find("moved to " + (fs::path(dir_) / "quarantine" / name).string()),
              std::string::npos);
  }
  EXPECT_NE(warning_about(scenes / "notes.txt").find("unexpected name"), std::string::npos);
  EXPECT_NE(warning_about(scenes / "dir.json").find("a directory"), std::string::npos);
  EXPECT_NE(warning_about(scenes / "orphan.positions").find("positions of no scene"), std::string::npos);
  EXPECT_EQ(read(fs::path(dir_) / "quarantine" / "dir.json" / "inside"), "x");

  for (const std::string id : {"", "../escape", ".hidden", "a/b"}) {
    EXPECT_FALSE(store.save_scene(id, "{}").ok) << id;
    EXPECT_FALSE(store.save_positions(id, 0, {}).ok) << id;
    EXPECT_FALSE(store.remove_scene(id).ok) << id;
  }
  EXPECT_FALSE(fs::exists(fs::path(dir_) / "escape.json"));
}

TEST_F(StoreTest, SymlinksAreQuarantinedNeverFollowed) {
  SceneStore store;
  ASSERT_TRUE(store.open(dir_).ok);
  const fs::path scenes = fs::path(dir_) / "scenes";
  // Outside the data directory: a file that would load as a scene and as
  // positions, and a directory.
  write(root_ / "secret.json", "{\"secret\": true}");
  write(root_ / "secret.positions", R"({"format": "voxvis-positions/1", "t": 7, "moves": []})");
  fs::create_directory(root_ / "outside");
  write(root_ / "outside" / "x.json", "{}");
  ASSERT_TRUE(store.save_scene("good", "{}").ok);
  fs::create_symlink(root_ / "secret.json", scenes / "link.json");
  fs::create_symlink(root_ / "secret.positions", scenes / "good.positions");
  fs::create_directory_symlink(root_ / "outside", scenes / "linkdir.json");
  fs::create_symlink(root_ / "secret.json", scenes / ".tmp-link");
  fs::create_symlink(root_ / "nowhere", scenes / "dangling.json");

  SceneStore reopened;
  ASSERT_TRUE(reopened.open(dir_).ok);
  const auto loaded = reopened.load_all(warn_);
  ASSERT_EQ(loaded.size(), 1u);
  EXPECT_EQ(loaded[0].id, "good");
  EXPECT_EQ(loaded[0].json, "{}");
  EXPECT_FALSE(loaded[0].t.has_value()) << "positions read through a symlink";
  EXPECT_EQ(scene_dir_listing(), std::vector<std::string>{"good.json"});
  const std::vector<std::string> links = {".tmp-link", "dangling.json", "good.positions", "link.json",
                                          "linkdir.json"};
  EXPECT_EQ(quarantine_listing(), links);
  for (const std::string& name : links) {
    EXPECT_TRUE(fs::is_symlink(fs::path(dir_) / "quarantine" / name)) << "the link itself moves: " << name;
    EXPECT_NE(warning_about(scenes / name).find("symbolic link"), std::string::npos);
  }
  // The targets are untouched.
  EXPECT_EQ(read(root_ / "secret.json"), "{\"secret\": true}");
  EXPECT_TRUE(fs::exists(root_ / "secret.positions"));
  EXPECT_EQ(listing(root_ / "outside"), std::vector<std::string>{"x.json"});
}

TEST_F(StoreTest, SymlinkedScenesDirectoryIsQuarantined) {
  const fs::path elsewhere = root_ / "elsewhere";
  fs::create_directories(elsewhere);
  write(elsewhere / "x.json", "{}");
  write(elsewhere / ".tmp-x.json.1.0", "not ours to remove");
  fs::create_directory(dir_);
  fs::create_directory_symlink(elsewhere, fs::path(dir_) / "scenes");

  SceneStore store;
  const Status s = store.open(dir_);
  ASSERT_TRUE(s.ok) << s.str();
  EXPECT_FALSE(fs::is_symlink(fs::path(dir_) / "scenes"));
  EXPECT_TRUE(fs::is_directory(fs::path(dir_) / "scenes"));
  EXPECT_TRUE(fs::is_symlink(fs::path(dir_) / "quarantine" / "scenes"));
  EXPECT_EQ(listing(elsewhere), (std::vector<std::string>{".tmp-x.json.1.0", "x.json"}));
  EXPECT_TRUE(store.load_all(warn_).empty());
  ASSERT_EQ(warnings_.size(), 1u);
  EXPECT_NE(warning_about(fs::path(dir_) / "scenes").find("symbolic link"), std::string::npos);
  ASSERT_TRUE(store.save_scene("y", "{}").ok);
  EXPECT_EQ(listing(elsewhere), (std::vector<std::string>{".tmp-x.json.1.0", "x.json"}));
}

TEST_F(StoreTest, DataDirectoryMayBeASymlink) {
  fs::create_directory(root_ / "real");
  const std::string link = (root_ / "link").string();
  fs::create_directory_symlink(root_ / "real", link);
  SceneStore store;
  ASSERT_TRUE(store.open(link).ok);
  ASSERT_TRUE(store.save_scene("a", "{}").ok);
  write(root_ / "real" / "scenes" / "stray", "");
  SceneStore reopened;
  ASSERT_TRUE(reopened.open(link).ok);
  EXPECT_EQ(reopened.load_all(warn_).size(), 1u);
  EXPECT_EQ(listing(root_ / "real" / "quarantine"), std::vector<std::string>{"stray"});
}

TEST_F(StoreTest, QuarantineNamesNeverCollide) {
  SceneStore store;
  ASSERT_TRUE(store.open(dir_).ok);
  const fs::path scenes = fs::path(dir_) / "scenes";
  const fs::path quarantine = fs::path(dir_) / "quarantine";
  for (const std::string text : {"first", "second", "third"}) {
    write(scenes / "notes.txt", text);
    EXPECT_TRUE(store.load_all(warn_).empty());
  }
  EXPECT_EQ(quarantine_listing(), (std::vector<std::string>{"notes.txt", "notes.txt.1", "notes.txt.2"}));
  EXPECT_EQ(read(quarantine / "notes.txt"), "first");
  EXPECT_EQ(read(quarantine / "notes.txt.2"), "third");
  ASSERT_EQ(warnings_.size(), 3u);
  EXPECT_NE(warnings_[2].find("moved to " + (quarantine / "notes.txt.2").string()), std::string::npos);

  // A scene quarantined twice (refused by the engine, say): both files move.
  for (const std::string json : {"{1}", "{2}"}) {
    ASSERT_TRUE(store.save_scene("s", json).ok);
    ASSERT_TRUE(store.save_positions("s", 1, {}).ok);
    const Status s = store.quarantine("s");
    ASSERT_TRUE(s.ok) << s.str();
  }
  ASSERT_TRUE(store.save_scene("lone", "{}").ok);  // without positions
  ASSERT_TRUE(store.quarantine("lone").ok);
  EXPECT_TRUE(scene_dir_listing().empty());
  EXPECT_EQ(quarantine_listing(),
            (std::vector<std::string>{"lone.json", "notes.txt", "notes.txt.1", "notes.txt.2", "s.json",
                                      "s.json.1", "s.positions", "s.positions.1"}));
  EXPECT_EQ(read(quarantine / "s.json.1"), "{2}");
  EXPECT_TRUE(store.quarantine("never-existed").ok);
  EXPECT_FALSE(store.quarantine("../escape").ok);
}

TEST_F(StoreTest, QuarantineThroughASymlinkIsRefused) {
  SceneStore store;
  ASSERT_TRUE(store.open(dir_).ok);
  fs::create_directory(root_ / "outside");
  fs::create_directory_symlink(root_ / "outside", fs::path(dir_) / "quarantine");
  write(fs::path(dir_) / "scenes" / "notes.txt", "x");
  ASSERT_TRUE(store.save_scene("s", "{}").ok);
  EXPECT_EQ(store.load_all(warn_).size(), 1u);
  EXPECT_NE(warning_about(fs::path(dir_) / "scenes" / "notes.txt").find("left in place"), std::string::npos);
  const Status s = store.quarantine("s");
  EXPECT_FALSE(s.ok);
  EXPECT_EQ(s.field, (fs::path(dir_) / "quarantine").string());
  EXPECT_TRUE(listing(root_ / "outside").empty());
  EXPECT_EQ(scene_dir_listing(), (std::vector<std::string>{"notes.txt", "s.json"}));
}

TEST_F(StoreTest, NonFinitePositionsAreRefused) {
  SceneStore store;
  ASSERT_TRUE(store.open(dir_).ok);
  const double inf = std::numeric_limits<double>::infinity();
  const Status s = store.save_positions("a", 1, {{1, {0, 0, 0}}, {2, {0, inf, 0}}});
  EXPECT_FALSE(s.ok);
  EXPECT_EQ(s.field, "positions[1].center");
  EXPECT_FALSE(store.save_positions("a", std::nan(""), {}).ok);
  EXPECT_FALSE(store.save_positions("a", 2e10, {}).ok);
  EXPECT_FALSE(store.save_positions("a", 0, {{1, {0, 0, 1e13}}}).ok);
  const Status r = store.save_positions("a", 0, {{1, {0, 0, 0}, true, Quat(std::nan(""), 0, 0, 0)}});
  EXPECT_FALSE(r.ok);
  EXPECT_EQ(r.field, "positions[0].rotation");
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
