#include "voxvis/server/server.h"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <fstream>
#include <mutex>
#include <optional>
#include <sstream>
#include <thread>

#include <grpcpp/ext/health_check_service_server_builder_option.h>
#include <grpcpp/ext/proto_server_reflection_plugin.h>
#include <grpcpp/grpcpp.h>
#include <grpcpp/health_check_service_interface.h>
#include <grpcpp/impl/server_builder_option.h>
#include <grpcpp/resource_quota.h>

#include "process/cgroup_limits.h"
#include "process/health.h"
#include "rpc/service.h"
#include "scenes/metrics.h"
#include "scenes/pool.h"
#include "scenes/shard.h"
#include "scenes/store.h"
#include "scenes/verifier.h"
#include "serving/auth.h"
#include "wire/calls.h"

namespace voxvis::server {
namespace {

bool read_file(const std::string& path, std::string* out) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return false;
  std::ostringstream ss;
  ss << in.rdbuf();
  *out = ss.str();
  return static_cast<bool>(in) || in.eof();
}

/// A scene id from a file name: its stem, with characters outside
/// [A-Za-z0-9._-] replaced by '_'.
std::string id_from_path(const std::string& path) {
  std::string stem = path;
  if (auto slash = stem.find_last_of('/'); slash != std::string::npos) stem = stem.substr(slash + 1);
  if (auto dot = stem.find_last_of('.'); dot != std::string::npos && dot > 0) stem = stem.substr(0, dot);
  for (char& c : stem)
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '.' || c == '_' || c == '-')) c = '_';
  if (stem.size() > 64) stem.resize(64);
  if (stem.empty() || stem[0] == '.') stem = "scene" + stem;
  return stem;
}

/// The engine's own check of `options` (Scene::create validates them with
/// the description, before it allocates the grid): a one-voxel empty scene,
/// built and dropped, costs next to nothing.
Status check_scene_options(const SceneOptions& options) {
  SceneDesc probe;
  probe.grid = glm::ivec3(1);
  std::unique_ptr<Scene> scene;
  return Scene::create(probe, options, &scene);
}

/// Removes server reflection from one builder. Linking gRPC's reflection
/// library registers its plugin for every builder at static initialization,
/// so not asking for it is not enough to leave it out.
class WithoutReflection final : public grpc::ServerBuilderOption {
 public:
  void UpdateArguments(grpc::ChannelArguments*) override {}
  void UpdatePlugins(std::vector<std::unique_ptr<grpc::ServerBuilderPlugin>>* plugins) override {
    std::erase_if(*plugins, [](const std::unique_ptr<grpc::ServerBuilderPlugin>& p) {
      return p->name() == "proto_server_reflection";
    });
  }
};

class ServerImpl final : public Server {
 public:
  ~ServerImpl() override { shutdown(); }

  /// Starts the server: each step below, in order; the first that fails
  /// says why in `error` (naming the flag) and the caller shuts down what
  /// the earlier ones started.
  bool init(const ServerConfig& c, Log log, std::string* error) {
    config_ = c;
    log_ = std::move(log);
    if (!check_config(error)) return false;
    apply_machine_defaults();
    if (!open_resources(error)) return false;
    start_service();
    load_data_directory();
    if (!load_scene_files(error) || !listen(error)) return false;
    announce();
    return true;
  }

  int port() const override { return port_; }

  void shutdown() override {
    std::lock_guard<std::mutex> once(shutdown_mu_);
    if (stopped_) return;
    stopped_ = true;
    if (server_) {
      // NOT_SERVING, and the health Watch streams end now rather than when
      // the grace runs out.
      server_->GetHealthCheckService()->SetServingStatus(false);
      server_->GetHealthCheckService()->Shutdown();
      service_->begin_shutdown();
      const auto grace = std::chrono::system_clock::now() +
                         std::chrono::milliseconds(static_cast<long>(config_.shutdown_grace_s * 1000));
      server_->Shutdown(grace);
    }
    if (builds_) builds_->drain();  // Builds see the shutdown and stop early.
    if (pool_) pool_->drain();
    if (service_)
      log_(std::to_string(service_->dropped()) +
           " queued requests dropped without running since start (their clients had gone, "
           "or the server was stopping)");
    {
      std::lock_guard<std::mutex> lock(saver_mu_);
      saver_stop_ = true;
    }
    saver_cv_.notify_all();
    if (saver_.joinable()) saver_.join();
    if (service_) service_->save_positions();
    if (server_) {
      server_->Wait();
      log_("stopped");
    }
  }

 private:
  /// Step 1: the flags, each checked before anything starts.
  bool check_config(std::string* error) {
    if (config_.data_dir.empty()) return fail(error, "--data-dir is required");
    if (!(config_.save_period_s > 0.0)) return fail(error, "--save-period must be > 0 seconds");
    if (!(config_.max_view_lead_s >= 0.0 && config_.max_view_lead_s <= kMaxSceneTime))
      return fail(error, "--max-view-lead must be within [0, 1e10] seconds");
    if (!(config_.max_time_step_s > 0.0 && config_.max_time_step_s <= 2 * kMaxSceneTime))
      return fail(error, "--max-time-step must be within (0, 2e10] seconds");
    if (config_.tls_cert.empty() != config_.tls_key.empty())
      return fail(error, "--tls-cert and --tls-key go together");
    // Bad scene options are a start error, not a refusal of every scene (the
    // data directory's would be quarantined one by one).
    if (Status s = check_scene_options(config_.scene_options); !s)
      return fail(error, s.field == "occlusion_buffer" ? "--occlusion-buffer: " + s.message
                                                       : "scene options: " + s.str());
    if (config_.max_calls < 1) return fail(error, "--max-calls must be >= 1");
    if (!ShardIdentity::make(config_.shard, config_.fleet, &shard_, error)) return false;
    VerifyConfig& vc = verify_config_;
    if (!(config_.verify_fraction >= 0.0 && config_.verify_fraction <= 1.0))
      return fail(error, "--verify-fraction must be within [0, 1]");
    vc.fraction = config_.verify_fraction;
    {
      std::string message;
      if (!render::parse_resolution(config_.verify_resolution, &vc.width, &vc.height, &message))
        return fail(error, "--verify-resolution: " + message);
    }
    if (config_.verify_queue < 1) return fail(error, "--verify-queue must be >= 1");
    vc.queue = static_cast<std::size_t>(config_.verify_queue);
    {
      std::string message;
      if (!render::parse_platform(config_.egl_platform, &vc.context.platform, &message))
        return fail(error, "--egl-platform: " + message);
      if (config_.egl_device < -1) return fail(error, "--egl-device must be >= 0");
      vc.context.device = config_.egl_device;
    }
    if (config_.max_streams_per_connection < 1)
      return fail(error, "--max-streams-per-connection must be >= 1");
    grpc_memory_ =
        config_.grpc_memory_bytes != 0
            ? config_.grpc_memory_bytes
            : std::max<std::uint64_t>(256ull << 20, 4ull * std::uint64_t(config_.max_message_bytes));
    if (grpc_memory_ < std::uint64_t(config_.max_message_bytes) + (16ull << 20))
      return fail(error, "--grpc-memory-mib must exceed --max-message-mib by at least 16 MiB "
                         "(a message of the largest size must fit)");
    return true;
  }

  /// Step 2: workers and the memory budget, from the flags or the machine.
  void apply_machine_defaults() {
    // Defaults from the machine, or the container's limits when lower
    // (cgroup_limits.h).
    workers_ = config_.workers ? config_.workers : std::thread::hardware_concurrency();
    if (workers_ == 0) workers_ = 2;
    if (config_.workers == 0) {
      if (std::optional<unsigned> cpus = cgroup_cpu_limit(); cpus && *cpus < workers_) workers_ = *cpus;
    }
    budget_ = config_.memory_budget_bytes;
    if (budget_ == 0) {
      const long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGE_SIZE);
      std::uint64_t memory = pages > 0 && page > 0 ? std::uint64_t(pages) * std::uint64_t(page) : (8ull << 30);
      if (std::optional<std::uint64_t> limit = cgroup_memory_limit(); limit && *limit < memory) memory = *limit;
      budget_ = memory / 2;
    }
  }

  /// Step 3: the tokens, the data directory, the metrics and the verifier.
  bool open_resources(std::string* error) {
    if (!config_.tokens_file.empty()) {
      if (Status s = tokens_.load(config_.tokens_file); !s) return fail(error, "--tokens: " + s.str());
    }
    if (Status s = store_.open(config_.data_dir); !s) return fail(error, "--data-dir: " + s.str());
    try {
      metrics_ = config_.metrics_address.empty() ? make_null_metrics()
                                                 : make_prometheus_metrics(config_.metrics_address);
    } catch (const std::exception& e) {
      return fail(error, std::string("--metrics: ") + e.what());
    }

    const VerifyConfig& vc = verify_config_;
    if (vc.fraction > 0.0) {
      verifier_ = Verifier::start(vc, log_, error);
      if (!verifier_) return false;
      log_("verify mode: " + std::to_string(vc.fraction) + " of frames at " + std::to_string(vc.width) + "x" +
           std::to_string(vc.height) + " on " + verifier_->renderer_info().summary());
    }
    return true;
  }

  /// Step 4: the worker pools and the service.
  void start_service() {
    // A job that lets an exception escape (the service catches the engine's
    // own) is logged and counted; the server goes on.
    auto job_error = [this](const std::string& what) {
      log_("internal error in a worker job: " + what);
      metrics_->error("job", grpc::StatusCode::INTERNAL);
    };
    pool_ = std::make_unique<WorkerPool>(workers_, job_error);
    // Scene builds take seconds; on their own thread, at a lower priority,
    // they never hold a frame worker nor delay one for long.
    builds_ = std::make_unique<WorkerPool>(1, job_error, true);
    ServiceConfig sc;
    sc.scene_options = config_.scene_options;
    sc.memory_budget_bytes = budget_;
    sc.workers = workers_;
    sc.max_view_lead_s = config_.max_view_lead_s;
    sc.max_time_step_s = config_.max_time_step_s;
    sc.max_calls = config_.max_calls;
    sc.max_saved_scene_bytes = 4 * static_cast<std::uint64_t>(config_.max_message_bytes);
    sc.max_message_bytes = static_cast<std::uint64_t>(config_.max_message_bytes);
    sc.shard = shard_;
    if (shard_.enabled()) log_("serving as " + shard_.describe());
    service_ = std::make_unique<Service>(sc, *pool_, *builds_, store_, tokens_, *metrics_, log_);
    service_->set_verifier(verifier_.get());
  }

  /// Step 5: the scenes of the data directory; one that fails to load is
  /// quarantined, and the others are served.
  void load_data_directory() {
    // Scenes acknowledged in earlier runs, at their last saved positions.
    for (const StoredScene& st : store_.load_all(log_)) {
      // Another shard's (the fleet changed): kept on disk, not built, until
      // `voxvis rebalance` moves it there.
      if (std::string owner = shard_.other_owner(st.id); !owner.empty()) {
        service_->add_misplaced(st.id, owner);
        log_("scene '" + st.id + "' of the data directory belongs to shard '" + owner +
             "': kept, not served; `voxvis rebalance` moves it there");
        continue;
      }
      const std::vector<Move>* pos = st.t ? &st.positions : nullptr;
      if (Status s = service_->load_scene(st.id, st.json, st.json_path, pos, st.t, false); !s) {
        // One bad scene must not keep the others from being served.
        if (Status q = store_.quarantine(st.id); !q)
          log_("scene '" + st.id + "' not loaded: " + s.str() + "; cannot quarantine it: " + q.str());
        else
          log_("quarantined scene '" + st.id + "': " + s.str());
        continue;
      }
      log_("loaded scene '" + st.id + "' from the data directory");
    }
  }

  /// Step 6: the scenes of --scene (after the data directory's, which win).
  bool load_scene_files(std::string* error) {
    for (const std::string& arg : config_.scene_files) {
      // "ID=FILE" names the scene; a plain FILE is named after its stem.
      std::string id, path = arg;
      if (const auto eq = arg.find('='); eq != std::string::npos && arg.find('/') > eq) {
        id = arg.substr(0, eq);
        path = arg.substr(eq + 1);
        if (!valid_scene_id(id))
          return fail(error, "--scene " + arg + ": '" + id +
                                 "' is not a scene id (1-64 of [A-Za-z0-9._-], not starting with '.')");
      } else {
        id = id_from_path(path);
      }
      if (std::string owner = shard_.other_owner(id); !owner.empty())
        return fail(error, "--scene " + arg + ": scene '" + id + "' belongs to shard '" + owner +
                               "', not to this server ('" + shard_.self() + "'); load it there");
      if (service_->has_scene(id)) {
        log_("--scene " + path + ": scene '" + id +
             "' is already in the data directory; kept (delete it to load the file again)");
        continue;
      }
      std::string text;
      if (!read_file(path, &text)) return fail(error, "--scene " + path + ": cannot read the file");
      if (Status s = service_->load_scene(id, text, path, nullptr, std::nullopt, true); !s)
        return fail(error, "--scene: " + s.str());
      log_("created scene '" + id + "' from " + path);
    }
    return true;
  }

  /// Step 7's credentials: TLS when --tls-cert is given.
  bool credentials(std::shared_ptr<grpc::ServerCredentials>* creds, std::string* error) {
    if (!config_.tls_cert.empty()) {
      grpc::SslServerCredentialsOptions opts;
      grpc::SslServerCredentialsOptions::PemKeyCertPair pair;
      if (!read_file(config_.tls_key, &pair.private_key))
        return fail(error, "--tls-key " + config_.tls_key + ": cannot read the file");
      if (!read_file(config_.tls_cert, &pair.cert_chain))
        return fail(error, "--tls-cert " + config_.tls_cert + ": cannot read the file");
      opts.pem_key_cert_pairs.push_back(pair);
      *creds = grpc::SslServerCredentials(opts);
      // With TLS, calls without a known token are refused on their headers,
      // before their messages are read (gRPC allows this on TLS only).
      if (tokens_.enabled()) (*creds)->SetAuthMetadataProcessor(tokens_.gate());
    } else {
      *creds = grpc::InsecureServerCredentials();
    }
    return true;
  }

  /// Step 7: the gRPC server, listening, with its limits and the health service.
  bool listen(std::string* error) {
    std::shared_ptr<grpc::ServerCredentials> creds;
    if (!credentials(&creds, error)) return false;
    if (config_.reflection) grpc::reflection::InitProtoReflectionServerBuilderPlugin();
    grpc::ServerBuilder builder;
    builder.AddListeningPort(config_.listen, creds, &port_);
    builder.RegisterService(service_.get());
    // Our own health service (health.h), owned by the server; it replaces
    // gRPC's default one.
    auto health = std::make_unique<HealthService>();
    builder.RegisterService(health.get());
    builder.SetOption(std::make_unique<grpc::HealthCheckServiceServerBuilderOption>(std::move(health)));
    // Reflection answers without a token: only on request.
    if (!config_.reflection) builder.SetOption(std::make_unique<WithoutReflection>());
    builder.SetMaxReceiveMessageSize(config_.max_message_bytes);
    builder.SetMaxSendMessageSize(config_.max_message_bytes);
    // gRPC reads a whole message before it checks its size, so the size
    // limit does not bound memory; the quota does, for all connections
    // together (under pressure gRPC resets streams to stay within it).
    grpc::ResourceQuota quota("voxvis-server");
    quota.Resize(static_cast<std::size_t>(grpc_memory_));
    builder.SetResourceQuota(quota);
    builder.AddChannelArgument(GRPC_ARG_MAX_CONCURRENT_STREAMS, config_.max_streams_per_connection);
    // Dead peers are noticed (and their streams freed) within a minute.
    builder.AddChannelArgument(GRPC_ARG_KEEPALIVE_TIME_MS, 30000);
    builder.AddChannelArgument(GRPC_ARG_KEEPALIVE_TIMEOUT_MS, 10000);
    builder.AddChannelArgument(GRPC_ARG_HTTP2_MIN_RECV_PING_INTERVAL_WITHOUT_DATA_MS, 10000);
    builder.AddChannelArgument(GRPC_ARG_KEEPALIVE_PERMIT_WITHOUT_CALLS, 1);
    server_ = builder.BuildAndStart();
    if (!server_ || port_ == 0) return fail(error, "--listen " + config_.listen + ": cannot listen there");
    server_->GetHealthCheckService()->SetServingStatus("", true);
    server_->GetHealthCheckService()->SetServingStatus(v1::Visibility::service_full_name(), true);
    return true;
  }

  /// Step 8: the periodic save, what the server says about itself, the port file.
  void announce() {
    saver_ = std::thread([this] { save_loop(); });
    if (!tokens_.enabled()) log_("no --tokens: every client may create, delete, move and view");
    log_("listening on port " + std::to_string(port_) + " (" + std::to_string(workers_) +
         " workers, memory budget " + std::to_string(budget_ >> 20) + " MiB, gRPC buffers " +
         std::to_string(grpc_memory_ >> 20) + " MiB, at most " + std::to_string(config_.max_calls) +
         " calls)");
    if (!config_.metrics_address.empty())
      log_("metrics at http://" + config_.metrics_address.substr(0, config_.metrics_address.rfind(':')) +
           ":" + std::to_string(metrics_->port()) + "/metrics");
    if (!config_.port_file.empty()) {
      const std::string tmp = config_.port_file + ".tmp";
      std::ofstream(tmp) << port_ << "\n";
      std::rename(tmp.c_str(), config_.port_file.c_str());
    }
  }

  bool fail(std::string* error, const std::string& message) {
    *error = message;
    return false;
  }

  void save_loop() {
    std::unique_lock<std::mutex> lock(saver_mu_);
    const auto period = std::chrono::duration<double>(config_.save_period_s);
    while (!saver_cv_.wait_for(lock, period, [this] { return saver_stop_; })) {
      lock.unlock();
      service_->save_positions();
      lock.lock();
    }
  }

  ServerConfig config_;
  Log log_;
  // What init's steps decide and the later ones use.
  ShardIdentity shard_;
  VerifyConfig verify_config_;
  std::uint64_t grpc_memory_ = 0;  ///< gRPC's buffers, all connections together.
  unsigned workers_ = 0;
  std::uint64_t budget_ = 0;       ///< Memory budget of the scenes, bytes.
  TokenTable tokens_;
  SceneStore store_;
  std::unique_ptr<Metrics> metrics_;
  std::unique_ptr<Verifier> verifier_;  // Outlives the pool, whose jobs hand it frames.
  std::unique_ptr<WorkerPool> pool_;    // Frames, GetPvs, move batches.
  std::unique_ptr<WorkerPool> builds_;  // CreateScene's parse and build.
  std::unique_ptr<Service> service_;
  std::unique_ptr<grpc::Server> server_;
  int port_ = 0;

  std::thread saver_;
  std::mutex saver_mu_;
  std::condition_variable saver_cv_;
  bool saver_stop_ = false;  // Guarded by saver_mu_.

  std::mutex shutdown_mu_;
  bool stopped_ = false;
};

}  // namespace

std::unique_ptr<Server> Server::start(const ServerConfig& config, Log log, std::string* error) {
  auto s = std::make_unique<ServerImpl>();
  if (!s->init(config, std::move(log), error)) {
    s->shutdown();
    return nullptr;
  }
  return s;
}

}  // namespace voxvis::server
