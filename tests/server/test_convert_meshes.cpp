// Meshes and rotations through the wire's conversions: the client's to_proto,
// the bytes on the wire, and the server's desc_from_proto / moves_from_proto
// give back every double bit for bit, keep instanced meshes shared, and the
// scene file the server saves brings them back the same (shared again).
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <memory>

#include "meshes.h"
#include "voxvis/client.h"
#include "voxvis/format.h"
#include "wire/convert.h"

namespace voxvis::server {
namespace {

bool same_bits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

bool same_bits(const Vec3& a, const Vec3& b) {
  return same_bits(a.x, b.x) && same_bits(a.y, b.y) && same_bits(a.z, b.z);
}

bool same_bits(const Quat& a, const Quat& b) {
  return same_bits(a.w, b.w) && same_bits(a.x, b.x) && same_bits(a.y, b.y) && same_bits(a.z, b.z);
}

bool same_mesh(const Mesh& a, const Mesh& b) {
  if (a.vertices.size() != b.vertices.size() || a.triangles != b.triangles) return false;
  for (std::size_t i = 0; i < a.vertices.size(); ++i)
    if (!same_bits(a.vertices[i], b.vertices[i])) return false;
  return true;
}

/// A mesh whose coordinates are not short decimals (thirds, a negative
/// zero), so that any rounding on the way would show.
std::shared_ptr<const Mesh> awkward_mesh() {
  auto m = std::make_shared<Mesh>(*test::icosphere(1));
  for (Vec3& v : m->vertices) v = v / 3.0 + Vec3(1e-7, -0.0, 0.1);
  m->vertices[0].y = -0.0;
  return m;
}

/// Spheres, a box, and meshes: one mesh placed by three objects (two static,
/// one dynamic), a soup rotated by a quaternion a little off unit norm (as
/// an exporter writes one), a cube scaled.
SceneDesc mesh_scene() {
  SceneDesc d;
  d.bounds_min = Vec3(0.0);
  d.bounds_max = Vec3(20.0);
  d.grid = glm::ivec3(16, 16, 16);
  const std::shared_ptr<const Mesh> shared = awkward_mesh();
  d.objects.push_back(test::mesh_object(4, shared, Vec3(5.1, 5.2, 5.3), test::rotation_about(Vec3(1, 2, 3), 0.7)));
  d.objects.push_back(test::mesh_object(5, test::triangle_soup(40, 7), Vec3(12.25, 3.0 / 7.0, 9.0),
                                        test::rotation_about(Vec3(0, 1, 0), 1.0) * (1.0 + 4e-7), 1.0 / 3.0));
  d.objects.push_back(test::mesh_object(6, shared, Vec3(15.0, 15.0, 15.0), Quat(1, 0, 0, 0), 2.5));
  ObjectDesc dyn = test::mesh_object(7, shared, Vec3(10.0, 2.0, 17.0), test::rotation_about(Vec3(0, 0, 1), 2.0));
  dyn.dynamic = true;
  dyn.max_speed = 3.5;
  d.objects.push_back(dyn);
  d.objects.push_back(test::mesh_object(8, test::cube_mesh(Vec3(0.5, 0.25, 1.0 / 3.0)), Vec3(3, 16, 4)));
  ObjectDesc s;
  s.id = 9;
  s.center = Vec3(1.0 / 3.0, 2, 3);
  s.radius = 0.7;
  d.objects.push_back(s);
  ObjectDesc b;
  b.id = 10;
  set_box_corners(Vec3(1, 1, 1), Vec3(2, 3, 4), &b);
  b.shape = Shape::Box;
  d.objects.push_back(b);
  return d;
}

/// `d` sent as a client sends it: to_proto, serialized and parsed back.
v1::SceneDescription on_the_wire(const SceneDesc& d) {
  v1::SceneDescription p;
  client::to_proto(d, &p);
  std::string bytes;
  EXPECT_TRUE(p.SerializeToString(&bytes));
  v1::SceneDescription back;
  EXPECT_TRUE(back.ParseFromString(bytes));
  return back;
}

void expect_same_objects(const SceneDesc& got, const SceneDesc& want) {
  ASSERT_EQ(got.objects.size(), want.objects.size());
  for (std::size_t i = 0; i < want.objects.size(); ++i) {
    SCOPED_TRACE("object " + std::to_string(i));
    const ObjectDesc& a = got.objects[i];
    const ObjectDesc& b = want.objects[i];
    EXPECT_EQ(a.id, b.id);
    EXPECT_EQ(a.shape, b.shape);
    EXPECT_EQ(a.dynamic, b.dynamic);
    EXPECT_TRUE(same_bits(a.max_speed, b.max_speed));
    EXPECT_TRUE(same_bits(a.center, b.center));
    if (b.shape != Shape::Mesh) continue;
    EXPECT_TRUE(same_bits(a.rotation, b.rotation)) << a.rotation.w << " " << b.rotation.w;
    EXPECT_TRUE(same_bits(a.scale, b.scale));
    ASSERT_TRUE(a.mesh);
    EXPECT_TRUE(same_mesh(*a.mesh, *b.mesh));
  }
}

TEST(ConvertMeshes, SceneRoundTripIsBitExactAndKeepsInstancesShared) {
  const SceneDesc want = mesh_scene();
  const v1::SceneDescription wire = on_the_wire(want);
  // Three distinct meshes: the shared one goes once.
  ASSERT_EQ(wire.meshes_size(), 3);
  EXPECT_EQ(wire.objects(0).mesh().index(), 0u);
  EXPECT_EQ(wire.objects(1).mesh().index(), 1u);
  EXPECT_EQ(wire.objects(2).mesh().index(), 0u);
  EXPECT_EQ(wire.objects(3).mesh().index(), 0u);
  EXPECT_EQ(wire.objects(4).mesh().index(), 2u);
  EXPECT_EQ(wire.meshes(0).vertices_size(), static_cast<int>(3 * want.objects[0].mesh->vertices.size()));
  EXPECT_EQ(wire.meshes(0).triangles_size(), static_cast<int>(3 * want.objects[0].mesh->triangles.size()));
  EXPECT_TRUE(wire.objects(5).has_sphere());
  EXPECT_TRUE(wire.objects(6).has_box());

  SceneDesc got;
  const Status s = desc_from_proto(wire, &got);
  ASSERT_TRUE(s.ok) << s.str();
  expect_same_objects(got, want);
  EXPECT_EQ(got.objects[0].mesh, got.objects[2].mesh) << "instances share one mesh";
  EXPECT_EQ(got.objects[0].mesh, got.objects[3].mesh);
  EXPECT_NE(got.objects[0].mesh, got.objects[1].mesh);
  EXPECT_TRUE(std::signbit(got.objects[0].mesh->vertices[0].y)) << "-0.0 stays -0.0";

  // The server saves the scene as scene_to_json's text and reads it back at
  // a restart: the same bits, and the instances shared again.
  SceneDesc saved;
  FormatError err;
  ASSERT_TRUE(parse_scene(scene_to_json(got), "saved.json", &saved, &err)) << err.str();
  EXPECT_NE(saved.objects[0].mesh, saved.objects[2].mesh) << "the file holds each instance inline";
  share_identical_meshes(&saved);
  expect_same_objects(saved, want);
  EXPECT_EQ(saved.objects[0].mesh, saved.objects[2].mesh);
  EXPECT_EQ(saved.objects[0].mesh, saved.objects[3].mesh);
  EXPECT_NE(saved.objects[0].mesh, saved.objects[1].mesh);
  EXPECT_NE(saved.objects[1].mesh, saved.objects[4].mesh);
}

TEST(ConvertMeshes, SavedSceneBytesForeseesTheFile) {
  // Known before the text is made, each distinct mesh looked at once:
  // exactly the file's size.
  SceneDesc d = mesh_scene();
  const std::shared_ptr<const Mesh> big = test::icosphere(4);
  for (ObjectId id = 20; id < 26; ++id)
    d.objects.push_back(test::mesh_object(id, big, Vec3(1.0 + id / 3.0, 4, 5), test::rotation_about(Vec3(1, 0, 0), id)));
  const std::uint64_t file = scene_to_json(d).size();
  std::uint64_t meshes = 0;
  EXPECT_EQ(scene_json_bytes(d, &meshes), file);
  EXPECT_GT(meshes, file / 2);
  // Each instance is written in full: six more, six more copies of the mesh.
  for (ObjectId id = 30; id < 36; ++id)
    d.objects.push_back(test::mesh_object(id, big, Vec3(1.0 + id / 3.0, 6, 5)));
  const std::uint64_t more_file = scene_to_json(d).size();
  EXPECT_GT(static_cast<double>(more_file - file), 6 * 0.9 * static_cast<double>(big->vertices.size() * 3 * 15));
  EXPECT_EQ(scene_json_bytes(d), more_file);
}

TEST(ConvertMeshes, SharingNeedsTheSameBits) {
  SceneDesc d = mesh_scene();
  // A copy equal in value but for one sign of zero is another mesh.
  auto copy = std::make_shared<Mesh>(*d.objects[0].mesh);
  copy->vertices[0].y = 0.0;
  d.objects[2].mesh = copy;
  auto same = std::make_shared<Mesh>(*d.objects[0].mesh);
  d.objects[3].mesh = same;
  share_identical_meshes(&d);
  EXPECT_NE(d.objects[2].mesh, d.objects[0].mesh);
  EXPECT_EQ(d.objects[3].mesh, d.objects[0].mesh);
}

TEST(ConvertMeshes, PlacementDefaultsWhenAbsent) {
  SceneDesc want = mesh_scene();
  v1::SceneDescription wire = on_the_wire(want);
  v1::MeshInstance* m = wire.mutable_objects(4)->mutable_mesh();
  m->clear_center();
  m->clear_rotation();
  m->clear_scale();
  SceneDesc got;
  ASSERT_TRUE(desc_from_proto(wire, &got).ok);
  EXPECT_EQ(got.objects[4].center, Vec3(0.0));
  EXPECT_TRUE(same_bits(got.objects[4].rotation, Quat(1, 0, 0, 0)));
  EXPECT_EQ(got.objects[4].scale, 1.0);
}

TEST(ConvertMeshes, MoveRotationsRoundTripBitExact) {
  const Quat q = test::rotation_about(Vec3(1, -2, 0.5), 2.1) * (1.0 - 6e-7);
  const std::vector<Move> sent = {Move{7, Vec3(1.0 / 3.0, -0.0, 1e-300), true, q}, Move{9, Vec3(2, 3, 4)}};
  v1::MoveBatch batch;
  for (const Move& m : sent) client::to_proto(m, batch.add_moves());
  EXPECT_TRUE(batch.moves(0).has_rotation());
  EXPECT_FALSE(batch.moves(1).has_rotation()) << "no rotation: the mesh keeps its own";
  std::string bytes;
  ASSERT_TRUE(batch.SerializeToString(&bytes));
  v1::MoveBatch back;
  ASSERT_TRUE(back.ParseFromString(bytes));
  std::vector<Move> got;
  ASSERT_TRUE(moves_from_proto(back, &got).ok);
  ASSERT_EQ(got.size(), 2u);
  EXPECT_TRUE(got[0].has_rotation);
  EXPECT_TRUE(same_bits(got[0].rotation, q));
  EXPECT_TRUE(same_bits(got[0].center, sent[0].center));
  EXPECT_FALSE(got[1].has_rotation);
  // The client's own reading of a move.
  const Move m = client::from_proto(back.moves(0));
  EXPECT_TRUE(m.has_rotation);
  EXPECT_TRUE(same_bits(m.rotation, q));
}

TEST(ConvertMeshes, MoveRotationsChecked) {
  v1::MoveBatch batch;
  client::to_proto(Move{7, Vec3(1, 2, 3)}, batch.add_moves());
  client::to_proto(Move{8, Vec3(1, 2, 3), true, Quat(0.5, 0, 0, 0)}, batch.add_moves());
  std::vector<Move> got;
  Status s = moves_from_proto(batch, &got);
  EXPECT_EQ(s.str(),
            "batch.moves[1].rotation: must be a unit quaternion [w, x, y, z] (norm within 1e-06 of 1), got norm 0.5");
  batch.mutable_moves(1)->mutable_rotation()->set_w(std::numeric_limits<double>::quiet_NaN());
  s = moves_from_proto(batch.moves(), "moves", &got);
  EXPECT_EQ(s.field, "moves[1].rotation") << s.str();
  batch.mutable_moves(1)->mutable_rotation()->Clear();  // Present, all zero.
  s = moves_from_proto(batch, &got);
  EXPECT_EQ(s.field, "batch.moves[1].rotation") << s.str();
  EXPECT_NE(s.message.find("got norm 0"), std::string::npos) << s.message;
}

}  // namespace
}  // namespace voxvis::server
