// server_usage.cpp — scraping and reading the server's metrics (libcurl for
// HTTP: the well-kept client, already beside prometheus-cpp on every machine
// voxvis builds on).
#include "server_usage.h"

#include <cerrno>
#include <cstdlib>
#include <mutex>
#include <sstream>

#include <curl/curl.h>

namespace voxvis::cli {
namespace {

/// The value of a sample line `name{labels} value` or `name value` when its
/// name is `name` and (if `scene` is non-null) its labels hold scene="…".
bool sample(const std::string& line, const std::string& name, const std::string* scene, double* value) {
  if (line.compare(0, name.size(), name) != 0) return false;
  std::size_t at = name.size();
  if (at < line.size() && line[at] == '{') {
    const std::size_t close = line.find('}', at);
    if (close == std::string::npos) return false;
    if (scene != nullptr) {
      const std::string labels = line.substr(at + 1, close - at - 1);
      // Scene ids are [A-Za-z0-9._-] (docs/server.md): no quotes or escapes.
      const std::string want = "scene=\"" + *scene + "\"";
      const std::size_t p = labels.find(want);
      if (p == std::string::npos || (p > 0 && labels[p - 1] != ',')) return false;
    }
    at = close + 1;
  } else if (scene != nullptr) {
    return false;
  }
  if (at >= line.size() || line[at] != ' ') return false;
  const char* begin = line.c_str() + at + 1;
  char* end = nullptr;
  errno = 0;
  const double v = std::strtod(begin, &end);
  if (end == begin || errno != 0) return false;
  *value = v;
  return true;
}

std::size_t append(char* data, std::size_t size, std::size_t n, void* out) {
  static_cast<std::string*>(out)->append(data, size * n);
  return size * n;
}

}  // namespace

bool parse_server_usage(const std::string& text, const std::string& scene, ServerUsage* out,
                        std::string* error) {
  bool cpu = false, engine = false, frames = false;
  bool engine_cpu = false;
  double engine_cpu_seconds = 0.0;
  std::istringstream in(text);
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    double v = 0.0;
    if (sample(line, "process_cpu_seconds_total", nullptr, &v)) {
      out->cpu_seconds = v, cpu = true;
    } else if (sample(line, "voxvis_frame_engine_seconds_sum", &scene, &v)) {
      out->engine_seconds = v, engine = true;
    } else if (sample(line, "voxvis_frame_engine_cpu_seconds_total", &scene, &v)) {
      engine_cpu_seconds = v, engine_cpu = true;
    } else if (sample(line, "voxvis_frames_total", &scene, &v)) {
      out->frames = v, frames = true;
    }
  }
  // The engine's CPU time where the server counts it; else its frames' time
  // (which also counts waits for a core).
  if (engine_cpu) out->engine_seconds = engine_cpu_seconds, engine = true;
  const char* missing = !cpu      ? "process_cpu_seconds_total"
                        : !engine ? "voxvis_frame_engine_seconds_sum"
                        : !frames ? "voxvis_frames_total"
                                  : nullptr;
  if (missing == nullptr) return true;
  *error = std::string("the server's metrics have no ") + missing +
           (cpu ? " for scene '" + scene + "'" : std::string(" (a voxvis-server older than this client?)"));
  return false;
}

bool scrape_server_usage(const std::string& address, const std::string& scene, ServerUsage* out,
                         std::string* error) {
  static std::once_flag init;
  std::call_once(init, [] { curl_global_init(CURL_GLOBAL_DEFAULT); });
  CURL* curl = curl_easy_init();
  if (curl == nullptr) {
    *error = "cannot start an HTTP request (libcurl)";
    return false;
  }
  const std::string url = "http://" + address + "/metrics";
  std::string body;
  char message[CURL_ERROR_SIZE] = {};
  curl_easy_setopt(curl, CURLOPT_URL, url.c_str());
  curl_easy_setopt(curl, CURLOPT_WRITEFUNCTION, append);
  curl_easy_setopt(curl, CURLOPT_WRITEDATA, &body);
  curl_easy_setopt(curl, CURLOPT_ERRORBUFFER, message);
  curl_easy_setopt(curl, CURLOPT_TIMEOUT_MS, 5000L);
  curl_easy_setopt(curl, CURLOPT_NOSIGNAL, 1L);
  curl_easy_setopt(curl, CURLOPT_PROTOCOLS_STR, "http");
  const CURLcode rc = curl_easy_perform(curl);
  long status = 0;
  curl_easy_getinfo(curl, CURLINFO_RESPONSE_CODE, &status);
  curl_easy_cleanup(curl);
  if (rc != CURLE_OK) {
    *error = "cannot read " + url + ": " + (message[0] != '\0' ? message : curl_easy_strerror(rc));
    return false;
  }
  if (status != 200) {
    *error = "cannot read " + url + ": HTTP status " + std::to_string(status);
    return false;
  }
  if (!parse_server_usage(body, scene, out, error)) {
    *error = url + ": " + *error;
    return false;
  }
  return true;
}

}  // namespace voxvis::cli
