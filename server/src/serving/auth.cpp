// auth.cpp — tokens file parsing and the per-call bearer-token check.
#include "serving/auth.h"

#include <cerrno>
#include <cstring>
#include <fstream>
#include <optional>
#include <sstream>
#include <utility>
#include <vector>

namespace voxvis::server {
namespace {

constexpr std::size_t kMinTokenLength = 16;
constexpr std::size_t kMaxTokenLength = 512;
constexpr std::string_view kBearerPrefix = "Bearer ";

bool is_blank(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f'; }

std::vector<std::string_view> split_fields(std::string_view line) {
  std::vector<std::string_view> fields;
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && is_blank(line[i])) ++i;
    const std::size_t start = i;
    while (i < line.size() && !is_blank(line[i])) ++i;
    if (i > start) fields.push_back(line.substr(start, i - start));
  }
  return fields;
}

std::optional<Role> parse_role(std::string_view name) {
  if (name == "viewer") return Role::Viewer;
  if (name == "simulation") return Role::Simulation;
  if (name == "admin") return Role::Admin;
  return std::nullopt;
}

// Printable ASCII without the space: anything else would not survive being
// copied into an HTTP/2 header value or a shell variable unchanged.
bool valid_token_char(char c) { return c > ' ' && c <= '~'; }

// Equal-length comparison whose time depends only on the presented token's
// length, never on how long a prefix matches: an attacker who can time calls
// must not be able to guess a token one character at a time. The presented
// length is the attacker's own input, so it leaks nothing.
bool constant_time_equal(std::string_view presented, std::string_view stored) {
  unsigned diff = presented.size() == stored.size() ? 0u : 1u;
  for (std::size_t i = 0; i < presented.size(); ++i) {
    const unsigned char s = i < stored.size() ? static_cast<unsigned char>(stored[i]) : 0u;
    diff |= static_cast<unsigned>(static_cast<unsigned char>(presented[i]) ^ s);
  }
  return diff == 0;
}

}  // namespace

const char* role_name(Role role) {
  switch (role) {
    case Role::Viewer: return "viewer";
    case Role::Simulation: return "simulation";
    case Role::Admin: return "admin";
  }
  return "unknown";
}

Status TokenTable::parse(std::string_view text, std::string_view source) {
  std::unordered_map<std::string, Role> roles;
  std::size_t line_no = 0;
  std::size_t pos = 0;
  while (pos < text.size()) {
    std::size_t end = text.find('\n', pos);
    if (end == std::string_view::npos) end = text.size();
    const std::string_view line = text.substr(pos, end - pos);
    pos = end + 1;
    ++line_no;
    const std::string where = std::string(source) + ":" + std::to_string(line_no);

    const std::vector<std::string_view> fields = split_fields(line);
    // Only whole-line comments: '#' is a legal token character.
    if (fields.empty() || fields[0].front() == '#') continue;
    if (fields.size() != 2) {
      return Status::Error(where, "expected 'role token' (two fields), found " +
                                      std::to_string(fields.size()) + " fields");
    }
    const std::optional<Role> role = parse_role(fields[0]);
    if (!role) {
      return Status::Error(where, "unknown role '" + std::string(fields[0]) +
                                      "' (expected viewer, simulation or admin)");
    }
    const std::string_view token = fields[1];
    // Errors about a token describe it but never quote it: the message may end
    // up in a log that is less protected than the tokens file.
    if (token.size() < kMinTokenLength || token.size() > kMaxTokenLength) {
      return Status::Error(where, "token is " + std::to_string(token.size()) +
                                      " characters; tokens have 16 to 512");
    }
    for (const char c : token) {
      if (!valid_token_char(c)) {
        return Status::Error(where, "token has a character that is not printable ASCII");
      }
    }
    if (!roles.emplace(std::string(token), *role).second) {
      return Status::Error(where, "duplicate token (a token may appear once)");
    }
  }
  if (roles.empty()) return Status::Error(std::string(source), "no tokens");
  roles_ = std::move(roles);
  enabled_ = true;
  return Status::Ok();
}

Status TokenTable::load(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return Status::Error(path, std::string("cannot open: ") + std::strerror(errno));
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) return Status::Error(path, std::string("cannot read: ") + std::strerror(errno));
  return parse(text.str(), path);
}

grpc::Status TokenTable::authorize_header(std::string_view authorization, bool present,
                                          Role need) const {
  if (!enabled_) return grpc::Status::OK;
  if (!present) {
    return grpc::Status(grpc::StatusCode::UNAUTHENTICATED,
                        "missing bearer token: send metadata 'authorization: Bearer <token>'");
  }
  if (authorization.substr(0, kBearerPrefix.size()) != kBearerPrefix ||
      authorization.size() == kBearerPrefix.size()) {
    return grpc::Status(grpc::StatusCode::UNAUTHENTICATED,
                        "malformed authorization metadata: expected 'Bearer <token>'");
  }
  const std::string_view token = authorization.substr(kBearerPrefix.size());
  // Every stored token is compared, whatever matches, so the time taken does
  // not tell which (or whether an early) entry matched. A hash-map lookup
  // would compare the full string against colliding entries with memcmp,
  // which stops at the first differing byte. The table holds a handful of
  // tokens, so the linear scan costs nothing measurable.
  std::optional<Role> held;
  for (const auto& [stored, role] : roles_) {
    if (constant_time_equal(token, stored)) held = role;
  }
  if (!held) {
    return grpc::Status(grpc::StatusCode::UNAUTHENTICATED, "unknown bearer token");
  }
  if (static_cast<int>(*held) < static_cast<int>(need)) {
    return grpc::Status(grpc::StatusCode::PERMISSION_DENIED,
                        std::string("this call needs the ") + role_name(need) +
                            " role; the token has " + role_name(*held));
  }
  return grpc::Status::OK;
}

grpc::Status TokenTable::authorize(const grpc::CallbackServerContext* context, Role need) const {
  if (!enabled_) return grpc::Status::OK;
  const auto& metadata = context->client_metadata();
  const auto [first, last] = metadata.equal_range("authorization");
  if (first == last) return authorize_header({}, false, need);
  // Two authorization entries are ambiguous: refuse rather than pick one.
  if (std::next(first) != last) {
    return grpc::Status(grpc::StatusCode::UNAUTHENTICATED,
                        "malformed authorization metadata: more than one value");
  }
  const grpc::string_ref& value = first->second;
  return authorize_header(std::string_view(value.data(), value.size()), true, need);
}

namespace {

class TokenGate final : public grpc::AuthMetadataProcessor {
 public:
  explicit TokenGate(const TokenTable& tokens) : tokens_(tokens) {}
  // Runs on the transport's thread: a few string comparisons.
  bool IsBlocking() const override { return false; }
  grpc::Status Process(const InputMetadata& metadata, grpc::AuthContext* /*context*/,
                       OutputMetadata* /*consumed*/, OutputMetadata* /*response*/) override {
    const auto path = metadata.find(":path");
    if (path != metadata.end() && path->second.starts_with("/grpc.health.v1.Health/"))
      return grpc::Status::OK;
    const auto [first, last] = metadata.equal_range("authorization");
    if (first == last) return tokens_.authorize_header({}, false, Role::Viewer);
    if (std::next(first) != last) {
      return grpc::Status(grpc::StatusCode::UNAUTHENTICATED,
                          "malformed authorization metadata: more than one value");
    }
    return tokens_.authorize_header(std::string_view(first->second.data(), first->second.size()),
                                    true, Role::Viewer);
  }

 private:
  const TokenTable& tokens_;
};

}  // namespace

std::shared_ptr<grpc::AuthMetadataProcessor> TokenTable::gate() const {
  return std::make_shared<TokenGate>(*this);
}

}  // namespace voxvis::server
