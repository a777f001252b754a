#include "wire/calls.h"

#include <algorithm>

#include <grpcpp/impl/codegen/proto_utils.h>
#include <grpcpp/support/proto_buffer_reader.h>

#include "voxvis/v1/voxvis.pb.h"

namespace voxvis::server {
namespace {

/// Descriptions past this are cut in the details (the text keeps all): a
/// client's metadata limit is 8 KiB by default, and one oversized trailer
/// can break later calls on the same connection.
constexpr std::size_t kMaxDescription = 1024;

std::string bad_request_details(const std::string& field, const std::string& description,
                                const std::string& text) {
  v1::BadRequest bad;
  v1::BadRequest::FieldViolation* v = bad.add_field_violations();
  v->set_field(field.substr(0, 256));
  v->set_description(description.substr(0, kMaxDescription));
  v1::ErrorStatus status;
  status.set_code(static_cast<int>(grpc::StatusCode::INVALID_ARGUMENT));
  status.set_message(text);
  google::protobuf::Any* any = status.add_details();
  // The standard type, so that clients with googleapis decode it as theirs.
  any->set_type_url("type.googleapis.com/google.rpc.BadRequest");
  any->set_value(bad.SerializeAsString());
  return status.SerializeAsString();
}

}  // namespace

grpc::Status invalid(const Status& s) {
  const std::string text = s.str();
  return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, text,
                      bad_request_details(s.field, s.message, text));
}

grpc::Status malformed(const std::string& type, std::size_t bytes) {
  return invalid(Status::Error("request", "not a valid " + type + " (" + std::to_string(bytes) +
                                              " bytes)"));
}

bool valid_scene_id(std::string_view id) {
  if (id.empty() || id.size() > 64 || id.front() == '.') return false;
  return std::all_of(id.begin(), id.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
           c == '.' || c == '_' || c == '-';
  });
}

grpc::Status check_scene_id(const std::string& id) {
  if (valid_scene_id(id)) return grpc::Status::OK;
  return invalid(Status::Error("scene_id", "must be 1-64 characters from [A-Za-z0-9._-], not "
                                           "starting with '.' (got " +
                                               std::to_string(id.size()) + " bytes)"));
}

grpc::Status no_scene(const std::string& id) {
  return grpc::Status(grpc::StatusCode::NOT_FOUND, "scene_id: no scene '" + id + "'");
}

grpc::Status deleted(const std::string& scene_id) {
  return grpc::Status(grpc::StatusCode::NOT_FOUND, "scene '" + scene_id + "' was deleted");
}

grpc::Status shutting_down_status() {
  return grpc::Status(grpc::StatusCode::UNAVAILABLE, "server is shutting down");
}

bool parse_message(const grpc::ByteBuffer& in, google::protobuf::MessageLite* out) {
  grpc::ByteBuffer copy(in);  // Shares the slices; the reader consumes its buffer.
  grpc::ProtoBufferReader reader(&copy);
  return reader.status().ok() && out->ParseFromZeroCopyStream(&reader);
}

grpc::Status serialize_message(const google::protobuf::MessageLite& m, grpc::ByteBuffer* out) {
  out->Clear();  // gRPC's writer requires an empty buffer; streams reuse theirs.
  bool own_buffer = false;
  return grpc::SerializationTraits<google::protobuf::MessageLite>::Serialize(m, out, &own_buffer);
}

}  // namespace voxvis::server
