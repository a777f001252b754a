// Wire messages to engine values: the same checks as the batch formats, with
// errors naming the message field.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "wire/convert.h"

namespace voxvis::server {
namespace {

v1::Vec3* set(v1::Vec3* v, double x, double y, double z) {
  v->set_x(x);
  v->set_y(y);
  v->set_z(z);
  return v;
}

v1::SceneDescription good_scene() {
  v1::SceneDescription d;
  set(d.mutable_bounds_min(), 0, 0, 0);
  set(d.mutable_bounds_max(), 10, 10, 10);
  v1::Object* s = d.add_objects();
  s->set_id(7);
  set(s->mutable_sphere()->mutable_center(), 1, 2, 3);
  s->mutable_sphere()->set_radius(0.5);
  s->set_dynamic(true);
  s->set_max_speed(2.0);
  v1::Object* b = d.add_objects();
  b->set_id(8);
  set(b->mutable_box()->mutable_min(), 1, 1, 1);
  set(b->mutable_box()->mutable_max(), 3, 2, 1);
  return d;
}

TEST(Convert, SceneDescriptionBecomesEngineInput) {
  SceneDesc desc;
  ASSERT_TRUE(desc_from_proto(good_scene(), &desc));
  ASSERT_EQ(desc.objects.size(), 2u);
  EXPECT_EQ(desc.objects[0].shape, Shape::Sphere);
  EXPECT_TRUE(desc.objects[0].dynamic);
  EXPECT_EQ(desc.objects[0].max_speed, 2.0);
  EXPECT_EQ(desc.objects[1].shape, Shape::Box);
  EXPECT_EQ(desc.objects[1].center, Vec3(2.0, 1.5, 1.0));
  EXPECT_EQ(desc.objects[1].half_extent, Vec3(1.0, 0.5, 0.0));
  EXPECT_FALSE(desc.grid.has_value());
}

TEST(Convert, BoxesComeBackTheSameFromTheSavedScene) {
  // The server saves a described scene as scene_to_json's text and reads that
  // after a restart: its boxes must come back exactly (corners such as these
  // came back an ulp off before set_box_corners).
  v1::SceneDescription d = good_scene();
  v1::Object* b = d.add_objects();
  b->set_id(9);
  set(b->mutable_box()->mutable_min(), 0.1, 0.2, 0.3);
  set(b->mutable_box()->mutable_max(), 0.7, 0.9, 0.35);
  SceneDesc desc;
  ASSERT_TRUE(desc_from_proto(d, &desc));
  SceneDesc saved;
  FormatError err;
  ASSERT_TRUE(parse_scene(scene_to_json(desc), "saved.json", &saved, &err)) << err.str();
  ASSERT_EQ(saved.objects.size(), desc.objects.size());
  for (std::size_t i = 0; i < desc.objects.size(); ++i) {
    EXPECT_EQ(saved.objects[i].center, desc.objects[i].center) << i;
    EXPECT_EQ(saved.objects[i].half_extent, desc.objects[i].half_extent) << i;
  }
  const ObjectDesc& o = desc.objects[2];
  EXPECT_LE(o.center.x - o.half_extent.x, 0.1);
  EXPECT_GE(o.center.x + o.half_extent.x, 0.7);
}

TEST(Convert, SceneErrorsNameTheField) {
  struct Case {
    const char* field;
    void (*mutate)(v1::SceneDescription*);
  };
  const double nan = std::numeric_limits<double>::quiet_NaN();
  static double s_nan;
  s_nan = nan;
  const Case cases[] = {
      {"description.bounds_min", [](v1::SceneDescription* d) { d->clear_bounds_min(); }},
      {"description.bounds_max", [](v1::SceneDescription* d) { set(d->mutable_bounds_max(), 10, 0, 10); }},
      {"description.grid.ny", [](v1::SceneDescription* d) {
         d->mutable_grid()->set_nx(4);
         d->mutable_grid()->set_ny(0);
         d->mutable_grid()->set_nz(4);
       }},
      {"description.objects[0].radius", [](v1::SceneDescription* d) { d->mutable_objects(0)->mutable_sphere()->set_radius(-1); }},
      {"description.objects[0].center", [](v1::SceneDescription* d) { d->mutable_objects(0)->mutable_sphere()->mutable_center()->set_y(s_nan); }},
      {"description.objects[0].center", [](v1::SceneDescription* d) { d->mutable_objects(0)->mutable_sphere()->mutable_center()->set_y(2e12); }},
      {"description.objects[0].max_speed", [](v1::SceneDescription* d) { d->mutable_objects(0)->set_max_speed(-1); }},
      {"description.objects[0].max_speed", [](v1::SceneDescription* d) { d->mutable_objects(0)->clear_max_speed(); }},
      {"description.objects[1].max_speed", [](v1::SceneDescription* d) { d->mutable_objects(1)->set_max_speed(1); }},
      {"description.objects[1].max", [](v1::SceneDescription* d) { set(d->mutable_objects(1)->mutable_box()->mutable_max(), 0, 2, 1); }},
      {"description.objects[1].min", [](v1::SceneDescription* d) { d->mutable_objects(1)->mutable_box()->clear_min(); }},
      {"description.objects[1]", [](v1::SceneDescription* d) { d->mutable_objects(1)->clear_box(); }},
  };
  for (const Case& c : cases) {
    v1::SceneDescription d = good_scene();
    c.mutate(&d);
    SceneDesc desc;
    const Status s = desc_from_proto(d, &desc);
    EXPECT_FALSE(s.ok) << c.field;
    EXPECT_EQ(s.field, c.field) << s.str();
  }
}

TEST(Convert, EngineErrorsGetThePathOrTheLine) {
  // Duplicate ids are the engine's check: put on the message path...
  const Status engine = Status::Error("objects[1].id", "duplicate id 7");
  EXPECT_EQ(scene_create_error(engine, false, "").str(), "description.objects[1].id: duplicate id 7");
  // ...or on the line of the JSON document.
  const std::string json =
      "{\n\"format\": \"voxvis-scene/1\",\n\"bounds\": {\"min\": [0,0,0], \"max\": [1,1,1]},\n"
      "\"objects\": [\n{\"id\": 7, \"shape\": \"sphere\", \"center\": [0,0,0], \"radius\": 1},\n"
      "{\"id\": 7, \"shape\": \"sphere\", \"center\": [0,0,0], \"radius\": 1}\n]}\n";
  EXPECT_NE(scene_create_error(engine, true, json).str().find("scene_json:6"), std::string::npos)
      << scene_create_error(engine, true, json).str();
}

TEST(Convert, JsonErrorsCarryTheLine) {
  SceneDesc desc;
  const Status s = desc_from_json("{\n\"format\": \"voxvis-scene/1\",\n\"bounds\": 3\n}", &desc);
  ASSERT_FALSE(s.ok);
  EXPECT_NE(s.str().find("scene_json:3"), std::string::npos) << s.str();
}

TEST(Convert, CameraChecksNameTheField) {
  v1::Camera c;
  set(c.mutable_eye(), 0, 0, 0);
  set(c.mutable_dir(), 0, 0, 1);
  set(c.mutable_up(), 0, 1, 0);
  c.set_fov_y_deg(60);
  c.set_aspect(1.5);
  c.set_near(0.1);
  c.set_far(100);
  Camera cam;
  EXPECT_TRUE(camera_from_proto(c, true, &cam));
  EXPECT_EQ(cam.aspect, 1.5);
  EXPECT_EQ(camera_from_proto(c, false, &cam).field, "camera");
  v1::Camera bad = c;
  bad.set_fov_y_deg(190);
  EXPECT_EQ(camera_from_proto(bad, true, &cam).field, "camera.fov_y_deg");
  bad = c;
  bad.clear_up();
  EXPECT_EQ(camera_from_proto(bad, true, &cam).field, "camera.up");
  bad = c;
  set(bad.mutable_up(), 0, 0, 2);
  EXPECT_EQ(camera_from_proto(bad, true, &cam).field, "camera.up");
  bad = c;
  bad.set_far(0.05);
  EXPECT_EQ(camera_from_proto(bad, true, &cam).field, "camera.far");
  // A region: unset is a point; set fields arrive as sent; bad ones named.
  EXPECT_TRUE(camera_from_proto(c, true, &cam));
  EXPECT_FALSE(is_region(cam));
  v1::Camera region = c;
  set(region.mutable_eye_extent(), 16, 4, 16);
  region.set_omnidirectional(true);
  region.set_horizon_s(0.1);
  EXPECT_TRUE(camera_from_proto(region, true, &cam));
  EXPECT_EQ(cam.eye_extent, Vec3(16, 4, 16));
  EXPECT_TRUE(cam.omnidirectional);
  EXPECT_EQ(cam.horizon_s, 0.1);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (const Vec3& e : {Vec3(-1, 0, 0), Vec3(0, nan, 0), Vec3(0, 0, 2e12)}) {
    bad = c;
    set(bad.mutable_eye_extent(), e.x, e.y, e.z);
    EXPECT_EQ(camera_from_proto(bad, true, &cam).field, "camera.eye_extent");
  }
  for (double h : {-0.5, nan, 1e10, std::numeric_limits<double>::infinity()}) {
    bad = c;
    bad.set_horizon_s(h);
    EXPECT_EQ(camera_from_proto(bad, true, &cam).field, "camera.horizon_s");
  }
}

TEST(Convert, MovesChecked) {
  v1::MoveBatch b;
  v1::Move* m = b.add_moves();
  m->set_id(3);
  set(m->mutable_center(), 1, 2, 3);
  std::vector<Move> moves;
  ASSERT_TRUE(moves_from_proto(b, &moves));
  ASSERT_EQ(moves.size(), 1u);
  EXPECT_EQ(moves[0].center, Vec3(1, 2, 3));
  v1::Move* twice = b.add_moves();
  *twice = *m;
  EXPECT_EQ(moves_from_proto(b, &moves).field, "batch.moves[1].id");
  b.mutable_moves(1)->set_id(4);
  b.mutable_moves(1)->clear_center();
  EXPECT_EQ(moves_from_proto(b, &moves).field, "batch.moves[1].center");
}

// The first offending move is named, whichever check it fails: ids are
// compared across the whole batch, centres move by move.
TEST(Convert, MovesNameTheFirstOffender) {
  const auto batch = [](std::vector<std::pair<ObjectId, double>> moves) {
    v1::MoveBatch b;
    for (const auto& [id, x] : moves) {
      v1::Move* m = b.add_moves();
      m->set_id(id);
      set(m->mutable_center(), x, 0, 0);
    }
    return b;
  };
  const double nan = std::numeric_limits<double>::quiet_NaN();
  std::vector<Move> moves;
  // 7 repeats at 2 and 4, 3 at 5: the first repeat is at 2.
  Status s = moves_from_proto(batch({{7, 0}, {3, 0}, {7, 0}, {9, 0}, {7, 0}, {3, 0}}), &moves);
  EXPECT_EQ(s.field, "batch.moves[2].id");
  EXPECT_NE(s.message.find("object 7 appears twice"), std::string::npos) << s.message;
  EXPECT_EQ(moves_from_proto(batch({{5, 0}, {3, 0}, {5, 0}, {3, 0}}), &moves).field, "batch.moves[2].id");
  EXPECT_EQ(moves_from_proto(batch({{5, 0}, {3, 0}, {6, 0}, {3, 0}}), &moves).field, "batch.moves[3].id");
  // A bad centre before the repeat is named first, and after it not.
  EXPECT_EQ(moves_from_proto(batch({{1, 0}, {2, nan}, {1, 0}}), &moves).field, "batch.moves[1].center");
  EXPECT_EQ(moves_from_proto(batch({{1, 0}, {1, 0}, {2, nan}}), &moves).field, "batch.moves[1].id");
  // Many distinct ids pass, in order.
  std::vector<std::pair<ObjectId, double>> many;
  for (ObjectId id = 1000; id > 0; --id) many.emplace_back(id, static_cast<double>(id));
  ASSERT_TRUE(moves_from_proto(batch(many), &moves));
  ASSERT_EQ(moves.size(), 1000u);
  EXPECT_EQ(moves.front().id, 1000u);
  EXPECT_EQ(moves.back().center, Vec3(1, 0, 0));
}

}  // namespace
}  // namespace voxvis::server
