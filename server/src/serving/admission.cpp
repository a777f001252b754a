#include "serving/admission.h"

#include <string>

namespace voxvis::server {

Admission::Admission(const TokenTable& tokens, Metrics& metrics, int max_calls)
    : tokens_(tokens), metrics_(metrics), max_calls_(max_calls) {}

grpc::Status Admission::enter_call() {
  if (calls_.fetch_add(1, std::memory_order_relaxed) < max_calls_) return grpc::Status::OK;
  calls_.fetch_sub(1, std::memory_order_relaxed);
  return grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED,
                      "server busy: " + std::to_string(max_calls_) + " calls in progress (--max-calls); try again");
}

void Admission::finish_unary(UnaryCall* r, const char* method, const grpc::Status& s) {
  if (!s.ok()) count_error(method, s);
  r->finish(s);
}

bool Admission::add_stream(Stream* s) {
  std::lock_guard<std::mutex> lock(streams_mu_);
  if (shutting_down_) return false;
  streams_.insert(s);
  return true;
}

void Admission::remove_stream(Stream* s) {
  std::lock_guard<std::mutex> lock(streams_mu_);
  streams_.erase(s);
}

void Admission::stop_streams(const SceneEntry& e, const grpc::Status& status) {
  std::lock_guard<std::mutex> lock(streams_mu_);
  for (Stream* s : streams_) s->stop_if(&e, status);
}

void Admission::begin_shutdown() {
  std::lock_guard<std::mutex> lock(streams_mu_);
  shutting_down_ = true;
  stopping_.store(true);
  for (Stream* s : streams_) s->stop_if(nullptr, shutting_down_status());
}

}  // namespace voxvis::server
