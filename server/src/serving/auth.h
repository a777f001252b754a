// auth.h — bearer tokens and roles.
//
// Roles nest: a viewer may view (View, Tick without moves, GetPvs,
// ListScenes, GetSceneStats), a simulation may also move objects (Simulate,
// Tick with moves), an admin may also create, delete and export scenes. Tokens come
// from a file (never the command line, where any user of the machine could
// read them in the process list):
//
//   # comment
//   admin      <token>
//   simulation <token>
//   viewer     <token>
//
// one role and one token per line, separated by white space. A token is 16 to
// 512 printable ASCII characters without white space; a token may appear once.
#pragma once

#include <memory>
#include <string>
#include <string_view>
#include <unordered_map>

#include <grpcpp/grpcpp.h>

#include "voxvis/types.h"

namespace voxvis::server {

enum class Role { Viewer = 0, Simulation = 1, Admin = 2 };

/// "viewer", "simulation" or "admin".
const char* role_name(Role role);

class TokenTable {
 public:
  /// Without tokens every call is allowed (the server then says so at start).
  bool enabled() const { return enabled_; }

  /// Reads a tokens file. On error returns a Status whose field is
  /// "<path>:<line>" and leaves the table unchanged.
  Status load(const std::string& path);

  /// Parses the text of a tokens file (`source` names it in errors).
  Status parse(std::string_view text, std::string_view source);

  /// OK when `need` is allowed for the call's "authorization: Bearer <token>"
  /// metadata; UNAUTHENTICATED when it is missing, malformed or unknown;
  /// PERMISSION_DENIED when the token's role is below `need`.
  grpc::Status authorize(const grpc::CallbackServerContext* context, Role need) const;

  /// The same check on the raw metadata value (for tests).
  grpc::Status authorize_header(std::string_view authorization, bool present, Role need) const;

  /// A gate for TLS credentials: refuses a call without a known token (any
  /// role; the handlers check roles) when its headers arrive, before gRPC
  /// reads its message, so an unauthenticated request costs no buffer
  /// however large it claims to be. The health service passes without a
  /// token. gRPC allows such a processor on TLS credentials only. The table
  /// must outlive the server.
  std::shared_ptr<grpc::AuthMetadataProcessor> gate() const;

 private:
  bool enabled_ = false;
  std::unordered_map<std::string, Role> roles_;
};

}  // namespace voxvis::server
