#include "voxvis/routing.h"

#include <openssl/sha.h>

#include <algorithm>
#include <cctype>
#include <set>

namespace voxvis::routing {

std::uint64_t weight(std::string_view shard_name, std::string_view scene_id) {
  std::string key;
  key.reserve(shard_name.size() + 1 + scene_id.size());
  key.append(shard_name);
  key.push_back('\n');
  key.append(scene_id);
  unsigned char digest[SHA256_DIGEST_LENGTH];
  SHA256(reinterpret_cast<const unsigned char*>(key.data()), key.size(), digest);
  std::uint64_t w = 0;
  for (int i = 0; i < 8; ++i) w = (w << 8) | digest[i];
  return w;
}

namespace {

template <class Name>
std::size_t owner_of(std::size_t count, Name name, std::string_view scene_id) {
  std::size_t best = 0;
  std::uint64_t best_weight = 0;
  for (std::size_t i = 0; i < count; ++i) {
    const std::uint64_t w = weight(name(i), scene_id);
    if (i == 0 || w > best_weight || (w == best_weight && name(i) < name(best))) {
      best = i;
      best_weight = w;
    }
  }
  return best;
}

bool ip_literal(std::string_view host) {
  if (!host.empty() && host.front() == '[') return true;  // [IPv6]
  return !host.empty() && std::all_of(host.begin(), host.end(), [](char c) {
    return std::isdigit(static_cast<unsigned char>(c)) || c == '.';
  });
}

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t')) s.remove_suffix(1);
  return s;
}

}  // namespace

std::size_t owner(const std::vector<std::string>& names, std::string_view scene_id) {
  return owner_of(names.size(), [&](std::size_t i) -> std::string_view { return names[i]; }, scene_id);
}

std::size_t owner(const std::vector<Shard>& shards, std::string_view scene_id) {
  return owner_of(shards.size(), [&](std::size_t i) -> std::string_view { return shards[i].name; }, scene_id);
}

bool valid_shard_name(std::string_view name, std::string* message) {
  if (name.empty() || name.size() > 253) {
    *message = "a shard name must be 1 to 253 characters, got " + std::to_string(name.size());
    return false;
  }
  for (const char c : name) {
    if (c <= ' ' || c > '~' || c == ',' || c == '=') {
      *message = "a shard name must be printable ASCII without spaces, ',' or '=': '" + std::string(name) + "'";
      return false;
    }
  }
  return true;
}

bool parse_servers(std::string_view list, std::vector<Shard>* shards, std::string* message) {
  shards->clear();
  std::set<std::string, std::less<>> names;
  std::size_t index = 0;
  while (true) {
    const std::size_t comma = list.find(',');
    const std::string_view entry = trim(list.substr(0, comma));
    const std::string where = "entry " + std::to_string(index + 1) + " ('" + std::string(entry) + "')";
    if (entry.empty()) {
      *message = "entry " + std::to_string(index + 1) + " is empty (the list is HOST:PORT,HOST:PORT,...)";
      return false;
    }
    if (++index > 4096) {
      *message = "more than 4096 servers";
      return false;
    }
    Shard shard;
    std::string_view address = entry;
    const std::size_t eq = entry.find('=');
    if (eq != std::string_view::npos) {
      shard.name = std::string(trim(entry.substr(0, eq)));
      address = trim(entry.substr(eq + 1));
    }
    const std::size_t colon = address.rfind(':');
    const std::string_view host = colon == std::string_view::npos ? std::string_view{} : address.substr(0, colon);
    const std::string_view port = colon == std::string_view::npos ? std::string_view{} : address.substr(colon + 1);
    const bool port_ok = !port.empty() && port.size() <= 5 &&
                         std::all_of(port.begin(), port.end(), [](char c) { return c >= '0' && c <= '9'; }) &&
                         std::stoul(std::string(port)) >= 1 && std::stoul(std::string(port)) <= 65535;
    if (host.empty() || !port_ok) {
      *message = where + ": not HOST:PORT with a port in 1..65535";
      return false;
    }
    shard.address = std::string(address);
    if (eq == std::string_view::npos) {
      shard.name = ip_literal(host) || host == "localhost" ? shard.address
                                                            : std::string(host.substr(0, host.find('.')));
    }
    std::string why;
    if (!valid_shard_name(shard.name, &why)) {
      *message = where + ": " + why;
      return false;
    }
    if (!names.insert(shard.name).second) {
      *message = where + ": shard name '" + shard.name +
                 "' is given twice (an entry without NAME= is named by its host's first label; "
                 "write NAME=HOST:PORT to tell them apart)";
      return false;
    }
    shards->push_back(std::move(shard));
    if (comma == std::string_view::npos) break;
    list.remove_prefix(comma + 1);
  }
  return true;
}

}  // namespace voxvis::routing
