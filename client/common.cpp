#include "common.h"

#include <algorithm>
#include <fstream>
#include <cstring>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>

#include "voxvis/client.h"
#include "voxvis/format.h"

namespace voxvis::cli {

bool read_file(const std::string& path, std::string* text, FormatError* error) {
  std::string message;
  if (client::read_whole(path, text, &message)) return true;
  *error = FormatError{path, 0, "", message};
  return false;
}

bool blank(const std::string& line) { return is_blank_line(line); }

bool read_frames(const std::string& path, const char* what, std::vector<FrameInput>* frames,
                 std::vector<int>* lines) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    report(FormatError{path, 0, "", std::string("cannot open: ") + std::strerror(errno)});
    return false;
  }
  FormatError error;
  const std::size_t first = frames->size();
  if (!parse_frames(in, path, frames, &error)) {
    report(error);
    return false;
  }
  if (frames->size() == first) {
    report(FormatError{path, 0, "", std::string("no frames in the file (") + what + " needs at least one)"});
    return false;
  }
  if (lines != nullptr) {
    for (std::size_t i = first; i < frames->size(); ++i) lines->push_back((*frames)[i].line);
  }
  return true;
}

double percentile(const std::vector<double>& sorted, double p) {
  if (sorted.empty()) return 0.0;
  const double rank = std::ceil(p / 100.0 * static_cast<double>(sorted.size()));
  const auto i = static_cast<std::size_t>(std::max(1.0, rank)) - 1;
  return sorted[std::min(i, sorted.size() - 1)];
}

Spread spread(std::vector<double> values) {
  Spread out;
  if (values.empty()) return out;
  std::sort(values.begin(), values.end());
  double sum = 0.0;
  for (const double v : values) sum += v;
  out.mean = sum / static_cast<double>(values.size());
  out.median = percentile(values, 50.0);
  out.p99 = percentile(values, 99.0);
  return out;
}

std::string with_commas(std::uint64_t n) {
  std::string digits = std::to_string(n);
  std::string out;
  out.reserve(digits.size() + digits.size() / 3);
  for (std::size_t i = 0; i < digits.size(); ++i) {
    if (i > 0 && (digits.size() - i) % 3 == 0) out += ',';
    out += digits[i];
  }
  return out;
}

void Progress::update(std::size_t frames) {
  if (!enabled_) return;
  const auto now = Clock::now();
  if (now - last_ < std::chrono::milliseconds(500)) return;
  last_ = now;
  const double secs = std::chrono::duration<double>(now - start_).count();
  const double fps = secs > 0.0 ? static_cast<double>(frames) / secs : 0.0;
  if (total_ > 0) {
    constexpr int kWidth = 30;
    const double done = std::min(1.0, static_cast<double>(frames) / static_cast<double>(total_));
    char bar[kWidth + 1];
    const int filled = static_cast<int>(done * kWidth);
    for (int i = 0; i < kWidth; ++i) bar[i] = i < filled ? '#' : '.';
    bar[kWidth] = '\0';
    const double left = fps > 0.0 ? static_cast<double>(total_ - std::min(frames, total_)) / fps : 0.0;
    std::fprintf(stderr, "\rvoxvis: [%s] %3.0f%% frame %zu of %zu, %.0f fps, %.0f s left\x1b[K", bar,
                 100.0 * done, frames, total_, fps, left);
  } else {
    std::fprintf(stderr, "\rvoxvis: frame %zu, %.0f fps\x1b[K", frames, fps);
  }
  std::fflush(stderr);
  shown_ = true;
}

void Progress::finish() {
  if (shown_) std::fputs("\r\x1b[K", stderr);
  shown_ = false;
}

int report_message(const std::string& message) {
  std::fprintf(stderr, "voxvis: error: %s\n", message.c_str());
  return kExitError;
}

int report_status(const grpc::Status& status, const std::string& address, const std::string& where,
                  bool protocol_error) {
  const std::string prefix = where.empty() ? "" : where + ": ";
  if (protocol_error) {
    // The server answered something the contract does not allow: not the
    // user's input, so an internal error.
    std::fprintf(stderr, "voxvis: internal error: %s%s\n", prefix.c_str(),
                 status.error_message().c_str());
    return kExitInternal;
  }
  std::fprintf(stderr, "voxvis: error: %s%s\n", prefix.c_str(),
               client::describe(status, address).c_str());
  return kExitError;
}

bool about_input(grpc::StatusCode code) {
  return code == grpc::StatusCode::INVALID_ARGUMENT || code == grpc::StatusCode::OUT_OF_RANGE ||
         code == grpc::StatusCode::FAILED_PRECONDITION ||
         code == grpc::StatusCode::RESOURCE_EXHAUSTED;
}

bool resolve_token(const NetArgs& net, std::string* token) {
  token->clear();
  std::string path = net.token_file;
  std::string origin = "--token-file";
  if (path.empty()) {
    const char* env = std::getenv("VOXVIS_TOKEN_FILE");
    if (env == nullptr || *env == '\0') return true;  // No token.
    path = env;
    origin = "VOXVIS_TOKEN_FILE";
  }
  std::string error;
  if (!client::load_token(path, token, &error)) {
    report_message(error + " (token file from " + origin + ")");
    return false;
  }
  return true;
}

std::unique_ptr<client::Client> open_client(const NetArgs& net, int* exit_code, int channel_index) {
  client::ConnectOptions options;
  options.address = net.server;
  options.tls_ca_file = net.tls_ca;
  options.tls_server_name = net.tls_server_name;
  options.channel_index = channel_index;
  if (!resolve_token(net, &options.token)) {
    *exit_code = kExitError;
    return nullptr;
  }
  std::string error;
  std::shared_ptr<grpc::Channel> channel = client::connect(options, &error);
  if (channel == nullptr) {
    *exit_code = report_message(error);
    return nullptr;
  }
  return std::make_unique<client::Client>(std::move(channel), options.token, net.server);
}

bool valid_scene_id(const std::string& id, std::string* message) {
  if (id.empty() || id.size() > 64) {
    *message = "must be 1 to 64 characters, got " + std::to_string(id.size());
    return false;
  }
  if (id[0] == '.') {
    *message = "must not start with '.', got '" + id + "'";
    return false;
  }
  for (const char c : id) {
    const bool ok = (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') ||
                    c == '.' || c == '_' || c == '-';
    if (!ok) {
      *message = "must use only the characters A-Z a-z 0-9 . _ -, got '" + id + "'";
      return false;
    }
  }
  return true;
}

}  // namespace voxvis::cli
