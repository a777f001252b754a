#include "process/health.h"

#include <optional>
#include <utility>

namespace voxvis::server {

using grpc::health::v1::HealthCheckRequest;
using grpc::health::v1::HealthCheckResponse;

/// One Watch call. It holds the last status sent and at most one waiting to
/// be sent; a newer status replaces the waiting one, so only the latest
/// reaches a slow reader.
class HealthService::WatchStream final : public grpc::ServerWriteReactor<HealthCheckResponse> {
 public:
  WatchStream(HealthService* owner, std::string name) : owner_(owner), name_(std::move(name)) {}

  const std::string& name() const { return name_; }

  /// Queues `status`; with `last`, the call ends (UNAVAILABLE) once it is sent.
  void update(ServingStatus status, bool last) {
    std::lock_guard<std::mutex> lock(mu_);
    if (finished_) return;
    pending_ = status;
    last_ = last_ || last;
    advance_locked();
  }

  void OnWriteDone(bool ok) override {
    std::lock_guard<std::mutex> lock(mu_);
    writing_ = false;
    if (!ok) finish_locked(grpc::Status(grpc::StatusCode::CANCELLED, "the client went away"));
    advance_locked();
  }

  void OnCancel() override {
    std::lock_guard<std::mutex> lock(mu_);
    finish_locked(grpc::Status(grpc::StatusCode::CANCELLED, "cancelled"));
  }

  void OnDone() override {
    owner_->forget(this);
    delete this;
  }

 private:
  void advance_locked() {
    if (finished_ || writing_) return;
    if (pending_ && (!sent_ || *pending_ != *sent_)) {
      sent_ = *pending_;
      pending_.reset();
      response_.set_status(*sent_);
      writing_ = true;
      StartWrite(&response_);
      return;
    }
    pending_.reset();
    if (last_) finish_locked(grpc::Status(grpc::StatusCode::UNAVAILABLE, "server is shutting down"));
  }

  void finish_locked(const grpc::Status& status) {
    if (finished_) return;
    finished_ = true;
    Finish(status);
  }

  HealthService* const owner_;
  const std::string name_;
  std::mutex mu_;
  std::optional<ServingStatus> pending_;  // Guarded by mu_.
  std::optional<ServingStatus> sent_;     // Guarded by mu_.
  HealthCheckResponse response_;          // Guarded by mu_; in use while writing_.
  bool writing_ = false;                  // Guarded by mu_.
  bool last_ = false;                     // Guarded by mu_.
  bool finished_ = false;                 // Guarded by mu_.
};

HealthService::HealthService() { status_[""] = HealthCheckResponse::SERVING; }

void HealthService::SetServingStatus(const std::string& service_name, bool serving) {
  std::lock_guard<std::mutex> lock(mu_);
  if (shut_down_) return;
  const ServingStatus status = serving ? HealthCheckResponse::SERVING : HealthCheckResponse::NOT_SERVING;
  status_[service_name] = status;
  notify_locked(service_name, status);
}

void HealthService::SetServingStatus(bool serving) {
  std::lock_guard<std::mutex> lock(mu_);
  if (shut_down_) return;
  const ServingStatus status = serving ? HealthCheckResponse::SERVING : HealthCheckResponse::NOT_SERVING;
  for (auto& [name, current] : status_) {
    current = status;
    notify_locked(name, status);
  }
}

void HealthService::Shutdown() {
  std::lock_guard<std::mutex> lock(mu_);
  if (shut_down_) return;
  shut_down_ = true;
  for (auto& entry : status_) entry.second = HealthCheckResponse::NOT_SERVING;
  for (WatchStream* stream : streams_) stream->update(HealthCheckResponse::NOT_SERVING, true);
}

grpc::ServerUnaryReactor* HealthService::Check(grpc::CallbackServerContext* context,
                                               const HealthCheckRequest* request,
                                               HealthCheckResponse* response) {
  grpc::ServerUnaryReactor* reactor = context->DefaultReactor();
  grpc::Status result;
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (const auto it = status_.find(request->service()); it != status_.end())
      response->set_status(it->second);
    else
      result = grpc::Status(grpc::StatusCode::NOT_FOUND, "service name unknown");
  }
  reactor->Finish(result);
  return reactor;
}

grpc::ServerWriteReactor<HealthCheckResponse>* HealthService::Watch(grpc::CallbackServerContext*,
                                                                    const HealthCheckRequest* request) {
  auto* stream = new WatchStream(this, request->service());
  std::lock_guard<std::mutex> lock(mu_);
  // Registered even after Shutdown: OnDone always finds it to forget.
  streams_.insert(stream);
  if (shut_down_) {
    stream->update(HealthCheckResponse::NOT_SERVING, true);
  } else {
    const auto it = status_.find(stream->name());
    stream->update(it != status_.end() ? it->second : HealthCheckResponse::SERVICE_UNKNOWN, false);
  }
  return stream;
}

void HealthService::notify_locked(const std::string& name, ServingStatus status) {
  for (WatchStream* stream : streams_)
    if (stream->name() == name) stream->update(status, false);
}

void HealthService::forget(WatchStream* stream) {
  std::lock_guard<std::mutex> lock(mu_);
  streams_.erase(stream);
}

}  // namespace voxvis::server
