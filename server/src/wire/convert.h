// convert.h — wire messages to engine values and back, with the checks of the
// batch formats. Errors are Status values whose field is the message path
// ("description.objects[3].radius", "camera.fov_y_deg", "batch.moves[0].id").
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "voxvis/format.h"
#include "voxvis/scene.h"
#include "voxvis/v1/voxvis.pb.h"

namespace voxvis::server {

/// A SceneDescription message as the engine's input. Checks what the scene
/// file's parser checks that Scene::create does not (a shape is set, box
/// corners ordered, coordinates within kMaxCoordinate, max_speed only on
/// dynamic objects, grid within 1..8192, every mesh of the table valid and
/// every mesh object's index and placement valid: voxvis/mesh.h's rules).
/// Objects naming one mesh share it.
Status desc_from_proto(const v1::SceneDescription& in, SceneDesc* out);

/// A voxvis-scene/1 document sent as text: parse errors carry its line
/// ("scene_json:12: objects[3].radius: must be > 0"). Identical meshes are
/// then shared (share_identical_meshes).
Status desc_from_json(const std::string& text, SceneDesc* out);

/// A Mesh message (SceneDescription.meshes[k]) as the engine's mesh: the
/// flat arrays cut into vertices and triangles (counts multiples of 3), then
/// validate_mesh's rules. Errors name `field` + ".vertices[i]" (vertex i),
/// ".triangles[t]" (triangle t) or the array.
Status mesh_from_proto(const v1::Mesh& in, const std::string& field, std::shared_ptr<const Mesh>* out);

/// A Quat message as the engine's, checked by validate_rotation (`field`
/// names it in errors).
Status quat_from_proto(const v1::Quat& in, const std::string& field, Quat* out);

/// Makes the mesh objects whose meshes hold the same bytes share one mesh.
/// The scene file writes every object's mesh inline, so a scene created with
/// instancing (a SceneDescription's mesh table) and saved as a file comes
/// back from it with its meshes shared again: its memory, and its estimate,
/// stay what they were when it was created.
void share_identical_meshes(SceneDesc* desc);

/// Puts an engine Status from Scene::create on the request's field path.
Status scene_create_error(const Status& engine, bool from_json, const std::string& json);

/// A camera message: present, then validate_camera's checks.
Status camera_from_proto(const v1::Camera& in, bool present, Camera* out);

/// A batch's moves: each id at most once, centre present and finite, a
/// rotation (when present) a unit quaternion. (Unknown and static ids, and
/// rotations of objects that are not meshes, are the engine's to refuse; it
/// names them the same way.)
Status moves_from_proto(const v1::MoveBatch& in, std::vector<Move>* out);
/// The same for a list of moves whose path is `path` ("moves": "moves[2].id").
Status moves_from_proto(const google::protobuf::RepeatedPtrField<v1::Move>& in, const std::string& path,
                        std::vector<Move>* out);

void stats_to_proto(const FrameStats& in, v1::FrameStats* out);
void vec_to_proto(const Vec3& in, v1::Vec3* out);

}  // namespace voxvis::server
