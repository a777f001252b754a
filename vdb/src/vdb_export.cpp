// vdb_export.cpp — voxvis/vdb.h on OpenVDB. The OpenVDB headers are heavy
// to compile, so they are included here only.
//
// Design choices:
//  * Index (i, j, k) of every grid is voxvis's voxel (i, j, k). OpenVDB
//    reads a voxel's value as lying at the voxel's centre, its cube spanning
//    index [i - 1/2, i + 1/2] (the cell-centred reading Houdini and Blender
//    draw), so the transform maps index (i, j, k) to the centre of voxvis's
//    voxel: a per-axis scale by voxel_size and a translation to bounds_min
//    + voxel_size / 2 (math::ScaleTranslateMap, which allows non-cubic
//    voxels). The cube OpenVDB draws for a voxel is then exactly voxvis's.
//  * Flags are BoolGrids (value true, active; background false, inactive),
//    the grid type every reader of .vdb files supports; the object counts an
//    Int32Grid. Boxes of the frame's record are filled as boxes
//    (sparseFill), so a hidden cell of 64^3 voxels is one tile, not 262,144
//    voxels; every grid is pruned before it is written.
//  * Every grid is written, empty or not, so that readers find them by name.
#include "voxvis/vdb.h"

#include <cmath>
#include <string>

#include <openvdb/openvdb.h>
#include <openvdb/io/File.h>
#include <openvdb/math/Transform.h>

namespace voxvis::vdb {
namespace {

/// The smallest voxel volume ScaleTranslateMap accepts (its constructor
/// throws below it), cubic world units.
double min_voxel_volume() { return 3.0 * openvdb::math::Tolerance<double>::value(); }

openvdb::Vec3d vec(const Vec3& v) { return openvdb::Vec3d(v.x, v.y, v.z); }

openvdb::math::Transform::Ptr grid_transform(const GridSpec& g) {
  const Vec3 centre0 = g.bounds_min + 0.5 * g.voxel_size;
  openvdb::math::MapBase::Ptr map(new openvdb::math::ScaleTranslateMap(vec(g.voxel_size), vec(centre0)));
  return openvdb::math::Transform::Ptr(new openvdb::math::Transform(map));
}

/// Names the grid, shares the transform and says what the grid holds.
template <class GridT>
typename GridT::Ptr make_grid(const char* name, const char* description,
                              const openvdb::math::Transform::Ptr& xform) {
  typename GridT::Ptr grid = GridT::create();
  grid->setName(name);
  grid->setTransform(xform);
  grid->setGridClass(openvdb::GRID_UNKNOWN);
  grid->setCreator("voxvis");
  grid->insertMeta("voxvis_description", openvdb::StringMetadata(description));
  return grid;
}

/// Fills a BoolGrid with boxes of voxels.
void fill_boxes(openvdb::BoolGrid& grid, const std::vector<VoxelBox>& boxes) {
  for (const VoxelBox& b : boxes)
    grid.sparseFill(openvdb::CoordBBox(openvdb::Coord(b.lo.x, b.lo.y, b.lo.z), openvdb::Coord(b.hi.x, b.hi.y, b.hi.z)),
                    true, true);
}

const char* traversal_name(FrameTrace::Traversal t) {
  switch (t) {
    case FrameTrace::Traversal::Cells:
      return "cells";
    case FrameTrace::Traversal::Voxels:
      return "voxels";
    case FrameTrace::Traversal::None:
      break;
  }
  return "none";
}

}  // namespace

Status check_grid(const GridSpec& grid) {
  const Vec3& v = grid.voxel_size;
  if (!(std::fabs(v.x * v.y * v.z) >= min_voxel_volume()))
    return Status::Error("bounds", "voxels of " + number_text(v.x) + " x " + number_text(v.y) + " x " +
                                       number_text(v.z) + " world units are too small for an OpenVDB transform " +
                                       "(their volume must be at least " + number_text(min_voxel_volume()) +
                                       "); export a coarser grid (--grid) or scale the scene");
  return Status::Ok();
}

Status write_vdb(const std::string& path, const Scene& scene, const std::string& source, const FrameGrids* frame,
                 ExportSummary* summary, bool read_back) {
  const GridSpec& g = scene.grid();
  if (Status st = check_grid(g); !st) return st;
  try {
    openvdb::initialize();
    const openvdb::math::Transform::Ptr xform = grid_transform(g);

    openvdb::BoolGrid::Ptr opaque =
        make_grid<openvdb::BoolGrid>("opaque", "voxels static objects cover (static opacity)", xform);
    openvdb::Int32Grid::Ptr objects = make_grid<openvdb::Int32Grid>(
        "objects", "number of objects touching each voxel, dynamic ones at their current centres", xform);
    {
      openvdb::BoolGrid::Accessor op = opaque->getAccessor();
      openvdb::Int32Grid::Accessor ob = objects->getAccessor();
      inspect_grid(scene, [&](const GridRow& row) {
        for (std::size_t x = 0; x < row.objects.size(); ++x) {
          const openvdb::Coord ijk(static_cast<int>(x), row.y, row.z);
          if (row.opaque[x]) op.setValueOn(ijk, true);
          if (row.objects[x] > 0) ob.setValueOn(ijk, static_cast<std::int32_t>(row.objects[x]));
        }
      });
    }
    openvdb::GridPtrVec grids{opaque, objects};

    openvdb::MetaMap meta;
    meta.insertMeta("voxvis_format", openvdb::StringMetadata("voxvis-vdb/1"));
    meta.insertMeta("voxvis_scene", openvdb::StringMetadata(source));
    meta.insertMeta("voxvis_grid_resolution", openvdb::Vec3IMetadata(openvdb::Vec3i(g.res.x, g.res.y, g.res.z)));
    meta.insertMeta("voxvis_bounds_min", openvdb::Vec3DMetadata(vec(g.bounds_min)));
    meta.insertMeta("voxvis_bounds_max", openvdb::Vec3DMetadata(vec(g.bounds_max)));
    meta.insertMeta("voxvis_voxel_size", openvdb::Vec3DMetadata(vec(g.voxel_size)));
    // After frame K that is frame K's time; 0 when no frame ran.
    meta.insertMeta("voxvis_time", openvdb::DoubleMetadata(scene.time()));

    if (frame != nullptr) {
      openvdb::BoolGrid::Ptr visited =
          make_grid<openvdb::BoolGrid>("visited", "voxels the frame's traversal reached and did not prove hidden", xform);
      openvdb::BoolGrid::Ptr occluded =
          make_grid<openvdb::BoolGrid>("occluded", "voxels the frame's traversal proved hidden", xform);
      openvdb::BoolGrid::Ptr pvs =
          make_grid<openvdb::BoolGrid>("pvs", "voxels touched by the objects of the frame's PVS", xform);
      fill_boxes(*visited, frame->trace->visited);
      fill_boxes(*occluded, frame->trace->occluded);
      {
        openvdb::BoolGrid::Accessor acc = pvs->getAccessor();
        inspect_grid(
            scene,
            [&](const GridRow& row) {
              for (std::size_t x = 0; x < row.objects.size(); ++x)
                if (row.objects[x] > 0) acc.setValueOn(openvdb::Coord(static_cast<int>(x), row.y, row.z), true);
            },
            frame->pvs);
      }
      grids.insert(grids.end(), {visited, occluded, pvs});
      const Camera& c = frame->camera;
      meta.insertMeta("voxvis_frame", openvdb::Int64Metadata(static_cast<std::int64_t>(frame->index)));
      meta.insertMeta("voxvis_traversal", openvdb::StringMetadata(traversal_name(frame->trace->traversal)));
      meta.insertMeta("voxvis_occlusion_buffer", openvdb::Int32Metadata(frame->occlusion_buffer));
      meta.insertMeta("voxvis_pvs_size", openvdb::Int64Metadata(static_cast<std::int64_t>(frame->pvs->size())));
      meta.insertMeta("voxvis_camera_eye", openvdb::Vec3DMetadata(vec(c.eye)));
      meta.insertMeta("voxvis_camera_dir", openvdb::Vec3DMetadata(vec(c.dir)));
      meta.insertMeta("voxvis_camera_up", openvdb::Vec3DMetadata(vec(c.up)));
      meta.insertMeta("voxvis_camera_fov_y_deg", openvdb::DoubleMetadata(c.fov_y_deg));
      meta.insertMeta("voxvis_camera_aspect", openvdb::DoubleMetadata(c.aspect));
      meta.insertMeta("voxvis_camera_near", openvdb::DoubleMetadata(c.near));
      meta.insertMeta("voxvis_camera_far", openvdb::DoubleMetadata(c.far));
    }
    for (const openvdb::GridBase::Ptr& grid : grids) grid->pruneGrid();
    if (summary != nullptr) {
      *summary = ExportSummary{};
      std::uint64_t* counts[] = {&summary->opaque, &summary->objects, &summary->visited, &summary->occluded,
                                 &summary->pvs};
      for (std::size_t i = 0; i < grids.size(); ++i) *counts[i] = grids[i]->activeVoxelCount();
    }
    openvdb::io::File file(path);
    file.write(grids, meta);
    // io::File does not report a stream that failed part way (a full
    // disk): the file is opened again and its grid descriptors read, which
    // catches a file cut short before its last grid.
    if (read_back) {
      openvdb::io::File back(path);
      back.open(false);
      for (const openvdb::GridBase::Ptr& grid : grids)
        if (!back.hasGrid(grid->getName()))
          return Status::Error("", "the file written does not read back: grid '" + grid->getName() + "' is missing");
      back.close();
    }
  } catch (const openvdb::Exception& e) {
    // IoError (cannot open or read back the file) and the like; others
    // (out of memory) are not the input's fault and propagate.
    return Status::Error("", std::string("OpenVDB: ") + e.what());
  }
  return Status::Ok();
}

}  // namespace voxvis::vdb
