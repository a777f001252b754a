// voxvis/vdb.h: files written in process, read back with OpenVDB's own
// reader and compared with what the engine reports (voxvis/inspect.h) and
// with expectations from the objects' bounds alone: grid names and types,
// the transform (non-cubic voxels), every active voxel, the metadata.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <tuple>
#include <vector>

#include <glm/common.hpp>
#include <glm/geometric.hpp>
#include <glm/vector_relational.hpp>
#include <openvdb/openvdb.h>
#include <openvdb/io/File.h>

#include "scenes.h"
#include "voxvis/inspect.h"
#include "voxvis/scene.h"
#include "voxvis/vdb.h"

namespace voxvis::test {
namespace {

using Voxel = std::tuple<int, int, int>;

/// Every active voxel of a grid with its value, tiles expanded.
template <class GridT>
std::map<Voxel, typename GridT::ValueType> active(const GridT& grid) {
  std::map<Voxel, typename GridT::ValueType> out;
  for (auto it = grid.cbeginValueOn(); it; ++it) {
    openvdb::CoordBBox b;
    it.getBoundingBox(b);
    for (int z = b.min().z(); z <= b.max().z(); ++z)
      for (int y = b.min().y(); y <= b.max().y(); ++y)
        for (int x = b.min().x(); x <= b.max().x(); ++x) out[Voxel(x, y, z)] = *it;
  }
  return out;
}

std::set<Voxel> voxels_of(const std::vector<VoxelBox>& boxes) {
  std::set<Voxel> out;
  for (const VoxelBox& b : boxes)
    for (int z = b.lo.z; z <= b.hi.z; ++z)
      for (int y = b.lo.y; y <= b.hi.y; ++y)
        for (int x = b.lo.x; x <= b.hi.x; ++x) out.insert(Voxel(x, y, z));
  return out;
}

template <class Map>
std::set<Voxel> keys(const Map& m) {
  std::set<Voxel> out;
  for (const auto& [k, v] : m) out.insert(k);
  return out;
}

/// The voxels (grid indices) a closed world box touches, from its bounds:
/// voxel i along an axis spans [min + i v, min + (i+1) v].
std::set<Voxel> box_voxels(const GridSpec& g, const Vec3& lo, const Vec3& hi) {
  std::set<Voxel> out;
  glm::ivec3 a, b;
  for (int k = 0; k < 3; ++k) {
    const double l = (lo[k] - g.bounds_min[k]) / g.voxel_size[k], h = (hi[k] - g.bounds_min[k]) / g.voxel_size[k];
    a[k] = std::max(0, static_cast<int>(std::ceil(l)) - 1);
    b[k] = std::min(g.res[k] - 1, static_cast<int>(std::floor(h)));
  }
  for (int z = a.z; z <= b.z; ++z)
    for (int y = a.y; y <= b.y; ++y)
      for (int x = a.x; x <= b.x; ++x) out.insert(Voxel(x, y, z));
  return out;
}

class VdbExport : public ::testing::Test {
 protected:
  void SetUp() override {
    openvdb::initialize();
    std::string tmpl = (std::filesystem::temp_directory_path() / "voxvis-vdb-XXXXXX").string();
    ASSERT_NE(::mkdtemp(tmpl.data()), nullptr);
    dir_ = tmpl;
  }
  void TearDown() override {
    std::error_code ec;
    std::filesystem::remove_all(dir_, ec);
  }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }

  /// Non-cubic voxels (0.5 x 1 x 2) off the origin: a wall in the middle of
  /// the view (grid x 3 to 12, every y), a crate before it, a ball behind
  /// it, a dynamic ball moved once.
  SceneDesc desc() const {
    SceneDesc d;
    d.bounds_min = Vec3(-4.0, 1.0, 10.0);
    d.bounds_max = Vec3(4.0, 9.0, 42.0);
    d.grid = glm::ivec3(16, 8, 16);
    d.objects = {box_between(1, wall_lo, wall_hi), box_between(2, crate_lo, crate_hi),
                 sphere(3, Vec3(0.3, 5.2, 37.0), 1.5), dynamic(sphere(4, Vec3(2.2, 3.3, 14.1), 0.6), 4.0)};
    return d;
  }
  const Vec3 wall_lo{-2.5, 1.0, 30.0}, wall_hi{2.5, 9.0, 32.0};
  const Vec3 crate_lo{-1.25, 3.5, 15.0}, crate_hi{0.75, 5.5, 19.0};
  std::filesystem::path dir_;
};

TEST_F(VdbExport, FrameGridsReadBackAsTheEngineHoldsThem) {
  for (int ob : {0, 160}) {
    SCOPED_TRACE("occlusion_buffer " + std::to_string(ob));
    SceneOptions options;
    options.occlusion_buffer = ob;
    std::unique_ptr<Scene> scene;
    ASSERT_TRUE(Scene::create(desc(), options, &scene).ok);
    const GridSpec& g = scene->grid();
    const Move move{4, Vec3(-2.7, 6.1, 13.4)};
    ASSERT_TRUE(scene->apply_moves(0.5, std::span<const Move>(&move, 1)).ok);
    const ViewerId viewer = scene->add_viewer();
    Scratch scratch;
    FrameTrace trace;
    scratch.set_trace(&trace);
    const Camera cam = camera_along(Vec3(0.1, 5.1, 11.0), Vec3(0.0, 0.0, 1.0), 50.0, 1.0, 0.05, 100.0);
    FrameResult r;
    ASSERT_TRUE(scene->frame(viewer, cam, 0.5, scratch, &r).ok);
    ASSERT_FALSE(trace.occluded.empty());
    ASSERT_FALSE(std::binary_search(r.pvs.begin(), r.pvs.end(), ObjectId{3}));  // Behind the wall.

    vdb::FrameGrids frame;
    frame.index = 7;
    frame.t = r.t;
    frame.camera = cam;
    frame.occlusion_buffer = static_cast<int>(r.stats.ob_width);
    frame.trace = &trace;
    frame.pvs = &r.pvs;
    vdb::ExportSummary sum;
    const std::string file_name = path("frame.vdb");
    const Status st = vdb::write_vdb(file_name, *scene, "scene.json", &frame, &sum);
    ASSERT_TRUE(st.ok) << st.str();

    openvdb::io::File file(file_name);
    ASSERT_TRUE(file.open());
    std::vector<std::string> names;
    for (auto it = file.beginName(); it != file.endName(); ++it) names.push_back(it.gridName());
    std::sort(names.begin(), names.end());
    EXPECT_EQ(names, (std::vector<std::string>{"objects", "occluded", "opaque", "pvs", "visited"}));
    const openvdb::MetaMap::Ptr meta = file.getMetadata();
    EXPECT_EQ(meta->metaValue<std::string>("voxvis_format"), "voxvis-vdb/1");
    EXPECT_EQ(meta->metaValue<std::string>("voxvis_scene"), "scene.json");
    EXPECT_EQ(meta->metaValue<std::int64_t>("voxvis_frame"), 7);
    EXPECT_EQ(meta->metaValue<double>("voxvis_time"), 0.5);
    EXPECT_EQ(meta->metaValue<std::string>("voxvis_traversal"), ob > 0 ? "cells" : "voxels");
    EXPECT_EQ(meta->metaValue<std::int64_t>("voxvis_pvs_size"), static_cast<std::int64_t>(r.pvs.size()));
    EXPECT_EQ(meta->metaValue<openvdb::Vec3i>("voxvis_grid_resolution"), openvdb::Vec3i(16, 8, 16));
    EXPECT_EQ(meta->metaValue<openvdb::Vec3d>("voxvis_camera_eye"), openvdb::Vec3d(0.1, 5.1, 11.0));

    const auto opaque = openvdb::gridPtrCast<openvdb::BoolGrid>(file.readGrid("opaque"));
    const auto objects = openvdb::gridPtrCast<openvdb::Int32Grid>(file.readGrid("objects"));
    const auto visited = openvdb::gridPtrCast<openvdb::BoolGrid>(file.readGrid("visited"));
    const auto occluded = openvdb::gridPtrCast<openvdb::BoolGrid>(file.readGrid("occluded"));
    const auto pvs = openvdb::gridPtrCast<openvdb::BoolGrid>(file.readGrid("pvs"));
    file.close();
    ASSERT_TRUE(opaque && objects && visited && occluded && pvs);

    // The transform: index (i, j, k) at the centre of voxel (i, j, k), and
    // any point of that voxel back to it.
    for (const auto& grid : {openvdb::GridBase::Ptr(opaque), openvdb::GridBase::Ptr(pvs)}) {
      const openvdb::math::Transform& xf = grid->transform();
      EXPECT_EQ(xf.voxelSize(), openvdb::Vec3d(0.5, 1.0, 2.0));
      const openvdb::Vec3d c = xf.indexToWorld(openvdb::Coord(3, 5, 7));
      EXPECT_NEAR(c.x(), -4.0 + 3.5 * 0.5, 1e-12);
      EXPECT_NEAR(c.y(), 1.0 + 5.5 * 1.0, 1e-12);
      EXPECT_NEAR(c.z(), 10.0 + 7.5 * 2.0, 1e-12);
      const openvdb::Coord back = xf.worldToIndexCellCentered(openvdb::Vec3d(-4.0 + 3.9 * 0.5, 1.0 + 5.1, 10.0 + 7.2 * 2.0));
      EXPECT_EQ(back, openvdb::Coord(3, 5, 7));
    }

    // What the engine reports, voxel by voxel.
    std::map<Voxel, std::int32_t> want_objects;
    std::set<Voxel> want_opaque, want_pvs;
    inspect_grid(*scene, [&](const GridRow& row) {
      for (int x = 0; x < g.res.x; ++x) {
        if (row.opaque[static_cast<std::size_t>(x)]) want_opaque.insert(Voxel(x, row.y, row.z));
        if (const std::uint32_t n = row.objects[static_cast<std::size_t>(x)])
          want_objects[Voxel(x, row.y, row.z)] = static_cast<std::int32_t>(n);
      }
    });
    inspect_grid(
        *scene,
        [&](const GridRow& row) {
          for (int x = 0; x < g.res.x; ++x)
            if (row.objects[static_cast<std::size_t>(x)]) want_pvs.insert(Voxel(x, row.y, row.z));
        },
        &r.pvs);
    EXPECT_EQ(keys(active(*opaque)), want_opaque);
    EXPECT_EQ(active(*objects), want_objects);
    EXPECT_EQ(keys(active(*visited)), voxels_of(trace.visited));
    EXPECT_EQ(keys(active(*occluded)), voxels_of(trace.occluded));
    EXPECT_EQ(keys(active(*pvs)), want_pvs);
    EXPECT_EQ(sum.opaque, want_opaque.size());
    EXPECT_EQ(sum.objects, want_objects.size());
    EXPECT_EQ(sum.visited, voxels_of(trace.visited).size());
    EXPECT_EQ(sum.occluded, voxels_of(trace.occluded).size());
    EXPECT_EQ(sum.pvs, want_pvs.size());

    // And from the objects' bounds alone: opaque, the wall's layer (grid
    // z = 10: world 30 to 32; x 3 to 12: world -2.5 to 2.5), the crate's
    // voxels wholly inside it and the static ball's wholly inside it; the
    // crate's touched range among the PVS voxels; the moved dynamic ball
    // counted where it went, not where it started.
    std::set<Voxel> covered;
    for (int z = 0; z < 16; ++z)
      for (int y = 0; y < 8; ++y)
        for (int x = 0; x < 16; ++x) {
          const Vec3 lo = g.bounds_min + Vec3(x, y, z) * g.voxel_size, hi = lo + g.voxel_size;
          const Vec3 ball(0.3, 5.2, 37.0);
          const double far_corner = glm::length(glm::max(glm::abs(lo - ball), glm::abs(hi - ball)));
          const bool in_crate = glm::all(glm::greaterThanEqual(lo, crate_lo)) && glm::all(glm::lessThanEqual(hi, crate_hi));
          if ((z == 10 && x >= 3 && x <= 12) || in_crate || far_corner < 1.5) covered.insert(Voxel(x, y, z));
        }
    EXPECT_EQ(keys(active(*opaque)), covered);
    const std::set<Voxel> crate = box_voxels(g, crate_lo, crate_hi);
    EXPECT_EQ(crate.size(), 5u * 3u * 3u);
    ASSERT_TRUE(std::binary_search(r.pvs.begin(), r.pvs.end(), ObjectId{2}));
    const std::set<Voxel> pvs_voxels = keys(active(*pvs));
    EXPECT_TRUE(std::includes(pvs_voxels.begin(), pvs_voxels.end(), crate.begin(), crate.end()));
    if (r.pvs == std::vector<ObjectId>{1, 2}) {
      std::set<Voxel> both = box_voxels(g, wall_lo, wall_hi);
      both.insert(crate.begin(), crate.end());
      EXPECT_EQ(pvs_voxels, both);
    }
    const auto counts = active(*objects);
    const auto start = counts.find(Voxel(12, 2, 2));  // (2.2, 3.3, 14.1): where the ball was.
    EXPECT_TRUE(start == counts.end()) << "the moved ball still counted at its first centre";
    EXPECT_EQ(counts.count(Voxel(2, 5, 1)), 1u);  // (-2.7, 6.1, 13.4): where it is.
  }
}

TEST_F(VdbExport, SceneAloneHasTwoGrids) {
  std::unique_ptr<Scene> scene;
  ASSERT_TRUE(Scene::create(desc(), SceneOptions{}, &scene).ok);
  vdb::ExportSummary sum;
  const Status st = vdb::write_vdb(path("scene.vdb"), *scene, "s.json", nullptr, &sum);
  ASSERT_TRUE(st.ok) << st.str();
  openvdb::io::File file(path("scene.vdb"));
  ASSERT_TRUE(file.open());
  std::vector<std::string> names;
  for (auto it = file.beginName(); it != file.endName(); ++it) names.push_back(it.gridName());
  std::sort(names.begin(), names.end());
  EXPECT_EQ(names, (std::vector<std::string>{"objects", "opaque"}));
  EXPECT_FALSE(file.getMetadata()->metaValue<std::string>("voxvis_format").empty());
  EXPECT_EQ((*file.getMetadata())["voxvis_frame"], nullptr);
  const auto objects = openvdb::gridPtrCast<openvdb::Int32Grid>(file.readGrid("objects"));
  ASSERT_TRUE(objects);
  // The dynamic ball at its initial centre (2.2, 3.3, 14.1): voxel (12, 2, 2).
  EXPECT_TRUE(objects->tree().isValueOn(openvdb::Coord(12, 2, 2)));
  EXPECT_EQ(objects->activeVoxelCount(), sum.objects);
}

TEST_F(VdbExport, VoxelsTooSmallForOpenVdbAreRefusedByName) {
  SceneDesc d;
  d.bounds_min = Vec3(0.0);
  d.bounds_max = Vec3(1e-4);
  d.grid = glm::ivec3(8);
  d.objects = {sphere(1, Vec3(5e-5), 1e-5)};
  std::unique_ptr<Scene> scene;
  ASSERT_TRUE(Scene::create(d, SceneOptions{}, &scene).ok);
  const Status st = vdb::write_vdb(path("tiny.vdb"), *scene, "tiny.json", nullptr);
  EXPECT_FALSE(st.ok);
  EXPECT_NE(st.message.find("too small for an OpenVDB transform"), std::string::npos) << st.str();
  EXPECT_FALSE(std::filesystem::exists(path("tiny.vdb")));
}

}  // namespace
}  // namespace voxvis::test
