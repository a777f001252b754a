// `voxvis verify` on this machine's EGL (llvmpipe in CI): the engine's PVS
// misses nothing on generated scenes, a PVS cut on purpose is caught to the
// object, what EGL shows only along an edge is dismissed, slices of a job
// concatenate to the whole, the CPU ray caster's reference agrees with EGL's
// but for ties, bad input is an error.
// Few frames at low resolutions: each frame costs milliseconds on llvmpipe.
#include <algorithm>
#include <cstdint>
#include <iterator>
#include <limits>
#include <set>
#include <string>
#include <unordered_map>
#include <vector>

#include <glm/geometric.hpp>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "cli_runner.h"
#include "files.h"
#include "scenes.h"
#include "voxvis/format.h"
#include "voxvis/generate.h"
#include "voxvis/raycast.h"

namespace voxvis::test {
namespace {

using ::testing::HasSubstr;
using ::testing::Not;

/// Where an object may be the first hit at the pixel centres of w x h when
/// every object may be off by `eps` of its distance from the eye (a margin
/// far above single-precision depths and silhouettes): `possible`, at some
/// pixel centre the object grown by that much is entered no later than every
/// other object shrunk by it; `robust`, at some pixel centre the object
/// shrunk by it is entered before every other object grown by it.
struct Firstness {
  std::set<ObjectId> possible;
  std::set<ObjectId> robust;
};

Firstness firstness(const std::vector<ObjectDesc>& objects, const Camera& cam, int w, int h, double eps) {
  raycast::ViewBasis b;
  EXPECT_TRUE(raycast::make_basis(cam, &b));
  constexpr double kNone = std::numeric_limits<double>::infinity();
  std::vector<ObjectDesc> grown = objects, shrunk = objects;
  std::vector<bool> has_shrunk(objects.size(), true);
  for (std::size_t i = 0; i < objects.size(); ++i) {
    const ObjectDesc& o = objects[i];
    const double size = o.shape == Shape::Sphere ? o.radius : std::max({o.half_extent.x, o.half_extent.y, o.half_extent.z});
    const double g = eps * (glm::length(o.center - b.eye) + size);
    if (o.shape == Shape::Sphere) {
      grown[i].radius += g;
      shrunk[i].radius -= g;
      has_shrunk[i] = shrunk[i].radius > 0.0;
    } else {
      grown[i].half_extent += Vec3(g);
      shrunk[i].half_extent -= Vec3(g);
      has_shrunk[i] = shrunk[i].half_extent.x >= 0.0 && shrunk[i].half_extent.y >= 0.0 && shrunk[i].half_extent.z >= 0.0;
    }
  }
  auto entry = [&](const ObjectDesc& o, const Vec3& d) {
    double t0 = 0.0, t1 = 0.0;
    if (!raycast::intersect(o, b.eye, d, &t0, &t1)) return kNone;
    const double in = std::max(t0, b.near);
    return in <= std::min(t1, b.far) ? in : kNone;
  };
  Firstness f;
  std::vector<double> eg(objects.size()), es(objects.size());
  for (int j = 0; j < h; ++j)
    for (int i = 0; i < w; ++i) {
      const Vec3 d = b.ray_dir(-1.0 + (2.0 * i + 1.0) / w, -1.0 + (2.0 * j + 1.0) / h);
      // The two least entries of each kind, so that "every other" is O(1).
      double g1 = kNone, g2 = kNone, s1 = kNone, s2 = kNone;
      for (std::size_t k = 0; k < objects.size(); ++k) {
        eg[k] = entry(grown[k], d);
        es[k] = has_shrunk[k] ? entry(shrunk[k], d) : kNone;
        if (eg[k] < g1) { g2 = g1; g1 = eg[k]; } else if (eg[k] < g2) { g2 = eg[k]; }
        if (es[k] < s1) { s2 = s1; s1 = es[k]; } else if (es[k] < s2) { s2 = es[k]; }
      }
      for (std::size_t k = 0; k < objects.size(); ++k) {
        if (eg[k] == kNone) continue;
        const double other_shrunk = es[k] == s1 ? s2 : s1;
        const double other_grown = eg[k] == g1 ? g2 : g1;
        if (eg[k] <= other_shrunk) f.possible.insert(objects[k].id);
        if (es[k] != kNone && es[k] < other_grown) f.robust.insert(objects[k].id);
      }
    }
  return f;
}

std::vector<std::uint64_t> ids_of(const nlohmann::json& a) {
  std::vector<std::uint64_t> v;
  for (const auto& x : a) v.push_back(x.get<std::uint64_t>());
  return v;
}

class Verify : public Cli {
 protected:
  /// Writes a scene and its camera path as frames (60 per second).
  void write(const ScenePath& sp, const std::string& scene, const std::string& frames) {
    spit(path(scene), scene_to_json(sp.scene));
    std::string text;
    for (std::size_t i = 0; i < sp.cameras.size(); ++i) {
      FrameInput f;
      f.t = static_cast<double>(i) / 60.0;
      f.camera = sp.cameras[i];
      text += frame_to_json(f) + "\n";
    }
    spit(path(frames), text);
  }
  /// paper.json and paper.jsonl: 600 spheres, 60 of them moving.
  void write_paper(int frames) { Cli::write_paper("paper.json", "paper.jsonl", 600, 60, frames); }
  /// The parsed output lines; checks their shape.
  std::vector<nlohmann::json> lines(const std::string& out) {
    std::vector<nlohmann::json> v;
    for (const std::string& l : lines_of(out)) {
      nlohmann::json j = nlohmann::json::parse(l, nullptr, false);
      EXPECT_FALSE(j.is_discarded()) << l;
      if (j.is_discarded()) continue;
      for (const char* key : {"frame", "visible", "missed", "edge_only", "pvs_size", "stats"})
        EXPECT_TRUE(j.contains(key)) << l;
      v.push_back(std::move(j));
    }
    return v;
  }
};

TEST_F(Verify, TheEnginesPvsMissesNothingOnGeneratedScenes) {
  struct Case {
    std::string name;
    ScenePath sp;
  };
  std::vector<Case> cases;
  cases.push_back({"indoor", make_indoor_level(2, 2, 8, 3)});
  cases.push_back({"cave", make_voxel_world(24, 8, true, 4)});
  cases.push_back({"surface", make_voxel_world(24, 8, false, 4)});
  cases.push_back({"city", make_city(2, 8, 5)});
  for (const Case& c : cases) {
    write(c.sp, c.name + ".json", c.name + ".jsonl");
    const Result r = run({"verify", "--scene", path(c.name + ".json"), "--frames", path(c.name + ".jsonl"),
                          "--resolution", "160x90"});
    ASSERT_EQ(r.status, 0) << c.name << "\n" << r.err;
    const auto out = lines(r.out);
    ASSERT_EQ(out.size(), c.sp.cameras.size()) << c.name;
    std::size_t seen = 0;
    for (std::size_t i = 0; i < out.size(); ++i) {
      EXPECT_EQ(out[i]["frame"].get<std::size_t>(), i);
      EXPECT_TRUE(out[i]["missed"].empty()) << c.name << ": " << out[i].dump();
      seen += out[i]["visible"].size();
      EXPECT_LE(out[i]["visible"].size(), out[i]["pvs_size"].get<std::size_t>());
    }
    EXPECT_GT(seen, out.size()) << c.name << ": hardly anything visible";
    EXPECT_THAT(r.err, HasSubstr("0 missed object-frames"));
    EXPECT_THAT(r.err, HasSubstr("tightness"));
  }
  // Moving objects, and the other method.
  write_paper(10);
  for (const std::vector<std::string>& extra :
       {std::vector<std::string>{}, std::vector<std::string>{"--method", "queries", "--full"}}) {
    std::vector<std::string> args = {"verify", "--scene", path("paper.json"), "--frames", path("paper.jsonl"),
                                     "--resolution", "128x72", "-q"};
    args.insert(args.end(), extra.begin(), extra.end());
    const Result r = run(args);
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_EQ(r.err, "");
    const auto out = lines(r.out);
    ASSERT_EQ(out.size(), 10u);
    for (const auto& j : out) EXPECT_TRUE(j["missed"].empty()) << j.dump();
  }
  // The two read-backs of the id image (the set gathered on the GPU, the
  // whole image), and of query results (a round at once, one by one), find
  // the same visible sets.
  const std::vector<std::vector<std::string>> ways = {{"--id-readback", "set"},
                                                      {"--id-readback", "image"},
                                                      {"--method", "queries", "--full", "--query-readback", "batch"},
                                                      {"--method", "queries", "--full", "--query-readback", "each"}};
  const std::vector<std::string> logged = {"ids read back as a", "ids read back as an image",
                                           "query results a round at once", "query results one by one"};
  std::vector<nlohmann::json> by[4];
  for (std::size_t k = 0; k < ways.size(); ++k) {
    std::vector<std::string> args = {"verify", "--scene", path("paper.json"), "--frames", path("paper.jsonl"),
                                     "--resolution", "128x72"};
    args.insert(args.end(), ways[k].begin(), ways[k].end());
    const Result r = run(args);
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_THAT(r.err, HasSubstr(logged[k]));
    for (const auto& j : lines(r.out)) by[k].push_back(j["visible"]);
    ASSERT_EQ(by[k].size(), 10u);
  }
  EXPECT_EQ(by[0], by[1]);
  EXPECT_EQ(by[2], by[3]);
}

TEST_F(Verify, FindsExactlyTheMissesOfACutPvs) {
  write_paper(12);
  Result r = run({"replay", "--scene", path("paper.json"), "--frames", path("paper.jsonl"), "--out",
                  path("pvs.jsonl"), "-q"});
  ASSERT_EQ(r.status, 0) << r.err;
  r = run({"verify", "--scene", path("paper.json"), "--frames", path("paper.jsonl"), "--pvs", path("pvs.jsonl"),
           "--resolution", "128x72", "-q"});
  ASSERT_EQ(r.status, 0) << r.err;
  const auto whole = lines(r.out);
  ASSERT_EQ(whole.size(), 12u);

  // Cut from every third frame its first two visible objects.
  std::string cut;
  std::vector<std::vector<std::uint64_t>> removed(whole.size());
  const std::vector<std::string> pvs_lines = lines_of(slurp(path("pvs.jsonl")));
  ASSERT_EQ(pvs_lines.size(), whole.size());
  for (std::size_t i = 0; i < pvs_lines.size(); ++i) {
    nlohmann::json j = nlohmann::json::parse(pvs_lines[i]);
    const auto vis = ids_of(whole[i]["visible"]);
    if (i % 3 == 0)
      for (std::size_t k = 0; k < std::min<std::size_t>(2, vis.size()); ++k) removed[i].push_back(vis[k]);
    nlohmann::json kept = nlohmann::json::array();
    for (const auto& id : j["pvs"])
      if (std::find(removed[i].begin(), removed[i].end(), id.get<std::uint64_t>()) == removed[i].end())
        kept.push_back(id);
    j["pvs"] = kept;
    cut += j.dump() + "\n";
  }
  spit(path("cut.jsonl"), cut);
  // Every cut object shows on faces, so the double-precision cones confirm
  // it: a miss, with either method (queries try every pixel).
  for (const std::vector<std::string>& extra :
       {std::vector<std::string>{}, std::vector<std::string>{"--method", "queries", "--full"}}) {
    std::vector<std::string> args = {"verify", "--scene", path("paper.json"), "--frames", path("paper.jsonl"),
                                     "--pvs", path("cut.jsonl"), "--resolution", "128x72"};
    args.insert(args.end(), extra.begin(), extra.end());
    r = run(args);
    EXPECT_EQ(r.status, 3) << r.err;
    const auto out = lines(r.out);
    ASSERT_EQ(out.size(), whole.size());
    std::size_t frames_cut = 0;
    for (std::size_t i = 0; i < out.size(); ++i) {
      EXPECT_EQ(ids_of(out[i]["missed"]), removed[i]) << "frame " << i;
      EXPECT_TRUE(out[i]["edge_only"].empty()) << "frame " << i;
      if (extra.empty()) {
        EXPECT_EQ(out[i]["visible"], whole[i]["visible"]) << "frame " << i;
      }
      if (!removed[i].empty()) {
        ++frames_cut;
        EXPECT_THAT(r.err, HasSubstr("MISS: frame " + std::to_string(i) + " "));
      }
    }
    EXPECT_GE(frames_cut, 3u);
    EXPECT_THAT(r.err, Not(HasSubstr("edge-only")));
  }
}

TEST_F(Verify, DismissesWhatEglShowsOnlyAlongAnEdge) {
  // Unit blocks, an eye at half-integer coordinates: in frame 0 at 160x90
  // the ray through one pixel centre crosses an edge where blocks meet, and
  // llvmpipe's single precision lets it through to block 611 behind them,
  // which no ray of positive measure reaches first (the double-precision
  // caster does not see it). Not a miss: reported under "edge_only".
  Result r = run({"generate", "--preset", "voxel-world", "--size", "24", "--frames", "8", "--seed", "4",
                  "--scene-out", path("world.json"), "--frames-out", path("world.jsonl")});
  ASSERT_EQ(r.status, 0) << r.err;
  const std::vector<std::string> base = {"verify", "--scene", path("world.json"), "--frames", path("world.jsonl"),
                                         "--resolution", "160x90", "--frame-count", "1"};
  auto with = [&](std::vector<std::string> extra) {
    std::vector<std::string> a = base;
    a.insert(a.end(), extra.begin(), extra.end());
    return a;
  };
  r = run(with({"--reference", "raycast", "-q"}));
  ASSERT_EQ(r.status, 0) << r.err;
  auto out = lines(r.out);
  ASSERT_EQ(out.size(), 1u);
  const auto cast = ids_of(out[0]["visible"]);
  EXPECT_EQ(std::count(cast.begin(), cast.end(), 611u), 0);
  EXPECT_TRUE(out[0]["edge_only"].empty());

  r = run(with({"--reference", "egl"}));
  if (r.status == 2 && r.err.find("error: EGL: ") != std::string::npos) GTEST_SKIP() << "no EGL: " << r.err;
  EXPECT_EQ(r.status, 0) << r.err;
  out = lines(r.out);
  ASSERT_EQ(out.size(), 1u);
  EXPECT_TRUE(out[0]["missed"].empty()) << out[0].dump();
  const auto egl = ids_of(out[0]["visible"]);
  if (std::count(egl.begin(), egl.end(), 611u) == 0)
    GTEST_SKIP() << "this EGL does not show block 611 through the edge (not llvmpipe's rounding?)";
  EXPECT_EQ(ids_of(out[0]["edge_only"]), std::vector<std::uint64_t>{611});
  EXPECT_THAT(r.err, HasSubstr("0 missed object-frames in 0 frames; 1 edge-only sightings dismissed"));
  EXPECT_THAT(r.err, Not(HasSubstr("MISS")));
  // With queries (no id image: every pixel is tried), the same.
  r = run(with({"--reference", "egl", "--method", "queries", "--full", "-q"}));
  EXPECT_EQ(r.status, 0) << r.err;
  out = lines(r.out);
  ASSERT_EQ(out.size(), 1u);
  EXPECT_TRUE(out[0]["missed"].empty()) << out[0].dump();
  EXPECT_EQ(ids_of(out[0]["edge_only"]), std::vector<std::uint64_t>{611});
  // A PVS that lacks a block the cones do see is still a miss.
  r = run({"replay", "--scene", path("world.json"), "--frames", path("world.jsonl"), "--out", path("pvs.jsonl"),
           "-q"});
  ASSERT_EQ(r.status, 0) << r.err;
  nlohmann::json first = nlohmann::json::parse(lines_of(slurp(path("pvs.jsonl")))[0]);
  std::vector<std::uint64_t> both;
  std::set_intersection(cast.begin(), cast.end(), egl.begin(), egl.end(), std::back_inserter(both));
  ASSERT_FALSE(both.empty());
  const std::uint64_t cut = both.front();
  nlohmann::json kept = nlohmann::json::array();
  for (const auto& id : first["pvs"])
    if (id.get<std::uint64_t>() != cut) kept.push_back(id);
  first["pvs"] = kept;
  spit(path("cut.jsonl"), first.dump() + "\n");
  r = run(with({"--reference", "egl", "--pvs", path("cut.jsonl"), "-q"}));
  EXPECT_EQ(r.status, 3) << r.err;
  out = lines(r.out);
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(ids_of(out[0]["missed"]), std::vector<std::uint64_t>{cut});
  EXPECT_EQ(ids_of(out[0]["edge_only"]), std::vector<std::uint64_t>{611});
}

TEST_F(Verify, SlicesConcatenateToTheWholeJob) {
  write_paper(9);
  auto strip = [](std::vector<nlohmann::json> v) {
    for (auto& j : v) j.erase("stats");  // Times differ run to run.
    return v;
  };
  Result r = run({"verify", "--scene", path("paper.json"), "--frames", path("paper.jsonl"), "--resolution",
                  "96x54", "-q"});
  ASSERT_EQ(r.status, 0) << r.err;
  const auto whole = strip(lines(r.out));
  ASSERT_EQ(whole.size(), 9u);
  std::vector<nlohmann::json> joined;
  for (const auto& [first, count] : std::vector<std::pair<int, int>>{{0, 4}, {4, 3}, {7, -1}}) {
    r = run({"verify", "--scene", path("paper.json"), "--frames", path("paper.jsonl"), "--resolution", "96x54",
             "-q", "--first-frame", std::to_string(first), "--frame-count", std::to_string(count)});
    ASSERT_EQ(r.status, 0) << r.err;
    for (auto& j : strip(lines(r.out))) joined.push_back(j);
  }
  EXPECT_EQ(joined, whole);
}

TEST_F(Verify, TheRayCasterAgreesWithEglButForTies) {
  // What may differ, at the same pixel centres: EGL's id buffer keeps one
  // object of a depth tie where the caster keeps all, and single-precision
  // depths and silhouettes may settle near-ties and grazing rays otherwise.
  // So every object the two disagree on is nowhere robustly the first hit
  // (Firstness, eps 1e-5); everything either sees is possibly first
  // somewhere; and with --method queries --full, which counts every object of
  // a tie, exact ties no longer differ.
  struct Totals {
    std::size_t robust = 0, only_cast = 0, only_egl = 0;
  };
  auto compare = [&](const std::string& scene, const std::string& frames, int w, int h,
                     const std::vector<std::string>& egl_extra, Totals* totals) {
    const std::string res = std::to_string(w) + "x" + std::to_string(h);
    const std::vector<std::string> base = {"verify", "--scene", path(scene), "--frames", path(frames),
                                           "--resolution", res, "-q"};
    std::vector<std::string> args = base;
    args.insert(args.end(), {"--reference", "raycast"});
    Result r = run(args);
    ASSERT_EQ(r.status, 0) << r.err;
    const auto cast = lines(r.out);
    args = base;
    args.insert(args.end(), {"--reference", "egl"});
    args.insert(args.end(), egl_extra.begin(), egl_extra.end());
    r = run(args);
    ASSERT_EQ(r.status, 0) << r.err;
    const auto egl = lines(r.out);
    ASSERT_EQ(cast.size(), egl.size());

    SceneDesc desc;
    FormatError error;
    ASSERT_TRUE(parse_scene(slurp(path(scene)), scene, &desc, &error)) << error.str();
    std::unordered_map<ObjectId, std::size_t> slot;
    for (std::size_t i = 0; i < desc.objects.size(); ++i) slot[desc.objects[i].id] = i;
    const std::vector<std::string> frame_lines = lines_of(slurp(path(frames)));
    ASSERT_EQ(frame_lines.size(), cast.size());
    for (std::size_t k = 0; k < cast.size(); ++k) {
      FrameInput f;
      ASSERT_TRUE(parse_frame_line(frame_lines[k], frames, static_cast<int>(k + 1), &f, &error)) << error.str();
      for (const Move& m : f.moves) desc.objects[slot.at(m.id)].center = m.center;
      const auto c = ids_of(cast[k]["visible"]), e = ids_of(egl[k]["visible"]);
      // verify's ray caster is the module's, at the pixel centres.
      const std::vector<ObjectId> by_hand =
          raycast::visible_objects(desc.objects, f.camera, raycast::pixel_centres(w, h));
      EXPECT_EQ(c, std::vector<std::uint64_t>(by_hand.begin(), by_hand.end())) << scene << " frame " << k;
      const Firstness first = firstness(desc.objects, f.camera, w, h, 1e-5);
      const std::set<std::uint64_t> cs(c.begin(), c.end()), es(e.begin(), e.end());
      for (const std::uint64_t id : cs) EXPECT_TRUE(first.possible.count(static_cast<ObjectId>(id))) << id;
      for (const std::uint64_t id : es)
        EXPECT_TRUE(first.possible.count(static_cast<ObjectId>(id)))
            << scene << " frame " << k << ": EGL sees " << id << ", which is nowhere nearly the first hit";
      for (const ObjectId id : first.robust) {
        EXPECT_TRUE(cs.count(id) && es.count(id))
            << scene << " frame " << k << ": " << id << " is robustly the first hit at some pixel centre, yet "
            << (cs.count(id) ? "EGL" : "the ray caster") << " misses it";
      }
      totals->robust += first.robust.size();
      for (const std::uint64_t id : cs) totals->only_cast += es.count(id) ? 0 : 1;
      for (const std::uint64_t id : es) totals->only_egl += cs.count(id) ? 0 : 1;
    }
  };

  // The paper's spheres, some moving: no exact ties.
  write_paper(5);
  Totals paper;
  compare("paper.json", "paper.jsonl", 80, 45, {}, &paper);
  EXPECT_GT(paper.robust, 50u);
  EXPECT_LE(paper.only_cast + paper.only_egl, 2u);

  // Boxes built to tie: a wall of abutting unit boxes seen head on (the
  // centre pixel of the odd image looks at a corner of four), and copies of
  // three of them and of a sphere, entered at the same depth on every ray.
  SceneDesc ties;
  ties.bounds_min = Vec3(-20.0);
  ties.bounds_max = Vec3(20.0);
  ObjectId id = 1;
  for (int x = -3; x < 3; ++x)
    for (int y = -3; y < 3; ++y) ties.objects.push_back(box_between(id++, Vec3(x, y, -11), Vec3(x + 1, y + 1, -10)));
  for (const ObjectId copy : {8u, 15u, 22u}) {
    ObjectDesc o = ties.objects[copy - 1];
    o.id = 100 + copy;
    ties.objects.push_back(o);
  }
  ties.objects.push_back(sphere(200, Vec3(1.5, -1.5, -6.0), 0.7));
  ties.objects.push_back(sphere(201, Vec3(1.5, -1.5, -6.0), 0.7));
  spit(path("ties.json"), scene_to_json(ties));
  std::string frames;
  for (const Vec3& eye : {Vec3(0.0), Vec3(0.5, 0.25, 0.0), Vec3(-1.0, 1.0, 2.0)}) {
    FrameInput f;
    f.camera = camera_along(eye, Vec3(0, 0, -1), 60.0, 1.0, 0.05, 100.0);
    frames += frame_to_json(f) + "\n";
  }
  spit(path("ties.jsonl"), frames);
  Totals ids;
  compare("ties.json", "ties.jsonl", 33, 33, {}, &ids);
  EXPECT_GE(ids.only_cast, 3u);  // At least the copies, one frame or another.
  EXPECT_EQ(ids.only_egl, 0u);
  Totals queries;
  compare("ties.json", "ties.jsonl", 33, 33, {"--method", "queries", "--full"}, &queries);
  EXPECT_EQ(queries.only_cast, 0u);
  EXPECT_EQ(queries.only_egl, 0u);
}

TEST_F(Verify, BadInputIsAClearError) {
  write_paper(4);
  const std::vector<std::string> base = {"verify", "--scene", path("paper.json"), "--frames", path("paper.jsonl")};
  auto with = [&](std::vector<std::string> extra) {
    std::vector<std::string> a = base;
    a.insert(a.end(), extra.begin(), extra.end());
    return a;
  };
  struct Case {
    std::vector<std::string> args;
    std::string message;
  };
  const std::string too_wide = "100000x16";
  spit(path("short.jsonl"), lines_of(slurp(path("paper.jsonl")))[0] + "\n");
  Result r = run({"replay", "--scene", path("paper.json"), "--frames", path("paper.jsonl"), "--out",
                  path("pvs.jsonl"), "-q"});
  ASSERT_EQ(r.status, 0) << r.err;
  const std::vector<std::string> pvs = lines_of(slurp(path("pvs.jsonl")));
  spit(path("few.jsonl"), pvs[0] + "\n" + pvs[1] + "\n");
  spit(path("many.jsonl"), slurp(path("pvs.jsonl")) + pvs[3] + "\n");
  spit(path("stranger.jsonl"), pvs[0] + "\n{\"frame\": 1, \"pvs\": [3, 99999]}\n");
  spit(path("order.jsonl"), pvs[1] + "\n");
  // Moves of objects the scene lacks or holds static, with a PVS file (no
  // engine to refuse them).
  nlohmann::json moved = nlohmann::json::parse(lines_of(slurp(path("paper.jsonl")))[0]);
  moved["moves"] = nlohmann::json::parse(R"([{"id": 987654, "center": [1, 2, 3]}])");
  spit(path("unknown_move.jsonl"), moved.dump() + "\n");
  moved["moves"] = nlohmann::json::parse(R"([{"id": 500, "center": [1, 2, 3]}])");  // Ids above 60 are static.
  spit(path("static_move.jsonl"), moved.dump() + "\n");
  spit(path("one_pvs.jsonl"), pvs[0] + "\n");
  const std::vector<Case> cases = {
      {{"verify", "--scene", path("paper.json"), "--frames", path("unknown_move.jsonl"), "--pvs",
        path("one_pvs.jsonl")},
       "unknown_move.jsonl:1: moves[0].id: unknown object id 987654"},
      {{"verify", "--scene", path("paper.json"), "--frames", path("static_move.jsonl"), "--pvs",
        path("one_pvs.jsonl")},
       "static_move.jsonl:1: moves[0].id: object 500 is static and cannot move"},
      {with({"--resolution", "0x10"}), "--resolution: width and height must be >= 1"},
      {with({"--resolution", "640"}), "--resolution: expected WIDTHxHEIGHT"},
      {with({"--resolution", "-5x10"}), "--resolution: expected WIDTHxHEIGHT"},
      {with({"--resolution", too_wide}), "--resolution: " + too_wide + " exceeds this OpenGL's limit"},
      {with({"--method", "magic"}), "--method: unknown method 'magic'"},
      {with({"--reference", "gpu"}), "--reference: unknown reference 'gpu' (known: auto, egl, raycast)"},
      {with({"--reference", "raycast", "--method", "queries"}),
       "--method: queries needs the EGL reference (not --reference raycast)"},
      {with({"--egl-platform", "x11"}), "--egl-platform: unknown EGL platform 'x11'"},
      {with({"--id-readback", "gpu"}), "--id-readback: unknown id read-back 'gpu' (known: auto, set, image)"},
      {with({"--query-readback", "lots"}), "--query-readback: unknown read-back 'lots' (known: batch, each)"},
      {with({"--egl-device", "7", "--egl-platform", "device"}), "--egl-device 7 does not exist"},
      {with({"--first-frame", "9"}), "--first-frame: is 9, the file has 4 frames"},
      {with({"--frame-count", "10"}), "--frame-count: asked for frames 0 to 9, the file has 4"},
      {with({"--pvs", path("few.jsonl")}), "few.jsonl: has no line for frame 2"},
      {with({"--pvs", path("many.jsonl")}), "many.jsonl:5: more PVS lines than frames"},
      {with({"--pvs", path("stranger.jsonl")}), "stranger.jsonl:2: pvs: id 99999 is not an object of the scene"},
      {with({"--pvs", path("order.jsonl")}), "order.jsonl:1: frame: expected 0"},
      {with({"--pvs", path("absent.jsonl")}), "absent.jsonl: cannot open"},
  };
  for (const Case& c : cases) {
    r = run(c.args);
    EXPECT_EQ(r.status, 2) << c.message << "\n" << r.err;
    EXPECT_EQ(r.signal, 0);
    EXPECT_THAT(r.err, HasSubstr("voxvis: error: ")) << c.message;
    EXPECT_THAT(r.err, HasSubstr(c.message)) << r.err;
  }
  // No EGL on the machine (glvnd finds no vendor library): --reference egl
  // fails, and so does a method only EGL has; auto falls back to the ray
  // caster and says so.
  const std::vector<std::string> no_egl = {"__EGL_VENDOR_LIBRARY_FILENAMES=/nonexistent/voxvis-no-egl.json"};
  r = run(with({"--reference", "egl"}), no_egl);
  EXPECT_EQ(r.status, 2) << r.err;
  EXPECT_EQ(r.signal, 0);
  EXPECT_THAT(r.err, HasSubstr("voxvis: error: EGL: no EGL implementation found"));
  EXPECT_EQ(r.out, "");
  r = run(with({"--method", "queries"}), no_egl);
  EXPECT_EQ(r.status, 2) << r.err;
  EXPECT_THAT(r.err, HasSubstr("voxvis: error: --method: queries needs the EGL reference (EGL: no EGL"));
  r = run(with({"--resolution", "64x36"}), no_egl);
  EXPECT_EQ(r.status, 0) << r.err;
  EXPECT_THAT(r.err, HasSubstr("verifying with the CPU ray caster"));
  EXPECT_THAT(r.err, HasSubstr("verifying at 64x36 by raycast on CPU ray caster"));
  const auto fallback = lines(r.out);
  ASSERT_EQ(fallback.size(), 4u);
  r = run(with({"--resolution", "64x36", "--reference", "raycast", "-q"}));
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(r.err, "");
  const auto cast = lines(r.out);
  ASSERT_EQ(cast.size(), fallback.size());
  for (std::size_t i = 0; i < cast.size(); ++i) EXPECT_EQ(cast[i]["visible"], fallback[i]["visible"]);
}

}  // namespace
}  // namespace voxvis::test
