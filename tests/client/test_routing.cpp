// Rendezvous hashing over a fleet's shard names (voxvis/routing.h): the
// weight is the documented SHA-256 prefix, owners spread evenly, a shard
// joining or leaving moves only the scenes it gains or held, and --servers
// lists parse with names from DNS labels.
#include <map>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "voxvis/routing.h"

namespace voxvis::routing {
namespace {

TEST(Routing, WeightIsTheDocumentedSha256Prefix) {
  // From Python's hashlib, the definition in docs/deploy.md:
  // int.from_bytes(hashlib.sha256((shard + "\n" + scene).encode()).digest()[:8], "big")
  EXPECT_EQ(weight("a", "match-0"), 7520946256867434058ull);
  EXPECT_EQ(weight("voxvis-1", "paper"), 13181658459075882437ull);
  EXPECT_EQ(weight("127.0.0.1:50051", "x"), 1457740764617823942ull);
}

std::string id(int i) { return "scene-" + std::to_string(i); }

TEST(Routing, OwnersSpreadEvenlyAndDoNotDependOnTheListsOrder) {
  const std::vector<std::string> names = {"voxvis-0", "voxvis-1", "voxvis-2"};
  const std::vector<std::string> reversed = {"voxvis-2", "voxvis-1", "voxvis-0"};
  std::map<std::string, int> count;
  const int n = 30000;
  for (int i = 0; i < n; ++i) {
    const std::string& owner_name = names[owner(names, id(i))];
    EXPECT_EQ(owner_name, reversed[owner(reversed, id(i))]);
    ++count[owner_name];
  }
  // Each third within 2 points (the binomial's standard deviation is 0.27).
  for (const auto& [name, c] : count) EXPECT_NEAR(double(c) / n, 1.0 / 3.0, 0.02) << name;
}

TEST(Routing, AJoiningOrLeavingShardMovesOnlyItsScenes) {
  const std::vector<std::string> three = {"a", "b", "c"};
  const std::vector<std::string> four = {"a", "b", "c", "d"};
  const std::vector<std::string> without_b = {"a", "c"};
  int to_d = 0;
  const int n = 20000;
  for (int i = 0; i < n; ++i) {
    const std::string before = three[owner(three, id(i))];
    const std::string after = four[owner(four, id(i))];
    if (after != before) {
      EXPECT_EQ(after, "d") << id(i);
      ++to_d;
    }
    const std::string left = without_b[owner(without_b, id(i))];
    if (before != "b") {
      EXPECT_EQ(left, before) << id(i);
    }
  }
  EXPECT_NEAR(double(to_d) / n, 0.25, 0.02);
}

TEST(Routing, ServerListsNameTheirShards) {
  std::vector<Shard> shards;
  std::string message;
  ASSERT_TRUE(parse_servers("voxvis-0.voxvis.default.svc.cluster.local:50051, voxvis-1.voxvis:50051,"
                            "127.0.0.1:7000,localhost:7001,[::1]:7002,edge=10.0.0.5:50051",
                            &shards, &message))
      << message;
  ASSERT_EQ(shards.size(), 6u);
  EXPECT_EQ(shards[0].name, "voxvis-0");
  EXPECT_EQ(shards[0].address, "voxvis-0.voxvis.default.svc.cluster.local:50051");
  EXPECT_EQ(shards[1].name, "voxvis-1");
  EXPECT_EQ(shards[2].name, "127.0.0.1:7000");
  EXPECT_EQ(shards[3].name, "localhost:7001");
  EXPECT_EQ(shards[4].name, "[::1]:7002");
  EXPECT_EQ(shards[5].name, "edge");
  EXPECT_EQ(shards[5].address, "10.0.0.5:50051");
  // The owner by the list is the owner by the names alone (what a server
  // started with --fleet computes).
  std::vector<std::string> names;
  for (const Shard& s : shards) names.push_back(s.name);
  for (int i = 0; i < 100; ++i) EXPECT_EQ(owner(shards, id(i)), owner(names, id(i)));

  const std::vector<std::pair<std::string, std::string>> bad = {
      {"", "entry 1 is empty"},
      {"a:1,", "entry 2 is empty"},
      {"host", "not HOST:PORT"},
      {"host:", "not HOST:PORT"},
      {":50051", "not HOST:PORT"},
      {"host:0", "port in 1..65535"},
      {"host:65536", "port in 1..65535"},
      {"host:12x", "port in 1..65535"},
      {"a.x:1,a.y:1", "shard name 'a' is given twice"},
      {"n=h:1,n=g:2", "shard name 'n' is given twice"},
      {"=h:1", "1 to 253 characters"},
      {"b c=h:1", "printable ASCII"},
  };
  for (const auto& [list, expected] : bad) {
    EXPECT_FALSE(parse_servers(list, &shards, &message)) << list;
    EXPECT_NE(message.find(expected), std::string::npos) << list << ": " << message;
  }
  std::string many;
  for (int i = 0; i < 4097; ++i) {
    if (i > 0) many += ',';
    many += 'h';
    many += std::to_string(i);
    many += ":1";
  }
  EXPECT_FALSE(parse_servers(many, &shards, &message));
  EXPECT_NE(message.find("more than 4096"), std::string::npos) << message;
}

}  // namespace
}  // namespace voxvis::routing
