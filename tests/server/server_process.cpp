#include "server_process.h"

#include <nlohmann/json.hpp>

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/socket.h>
#include <stdlib.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>

#include <grpcpp/generic/generic_stub.h>

#include "scenes.h"
#include "voxvis/format.h"

extern char** environ;

namespace voxvis::servertest {
namespace fs = std::filesystem;

namespace {
// An idle client channel notices a server's GOAWAY only when gRPC's backup
// poller runs (every 5 s by default), and a stopping server waits for its
// connections to close (up to its shutdown grace). Poll often, so that the
// tests' idle channels do not make every graceful stop last 5 s. Read once,
// when gRPC initializes: set before any channel exists (static
// initialization), unless the environment sets it.
[[maybe_unused]] const bool kFastBackupPoll = [] {
  ::setenv("GRPC_CLIENT_CHANNEL_BACKUP_POLL_INTERVAL_MS", "100", 0);
  return true;
}();
}  // namespace

// ---------------------------------------------------------------------------
// Files and processes

std::string make_temp_dir(const std::string& prefix) {
  std::string tmpl = (fs::temp_directory_path() / (prefix + "-XXXXXX")).string();
  if (::mkdtemp(tmpl.data()) == nullptr) {
    ADD_FAILURE() << "mkdtemp " << tmpl << ": " << std::strerror(errno);
    return {};
  }
  return tmpl;
}


ChildProcess::~ChildProcess() { kill9(); }

bool ChildProcess::spawn(const std::vector<std::string>& argv_s, const std::string& stdout_path,
                         const std::string& stderr_path, const std::vector<std::string>& env_add) {
  // Everything the child needs is prepared before fork: between fork and
  // exec only async-signal-safe calls are allowed (the test is threaded).
  std::vector<std::string> args = argv_s;
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  std::vector<std::string> env_s;
  for (char** e = environ; *e != nullptr; ++e) {
    const std::string entry = *e;
    const std::string name = entry.substr(0, entry.find('=') + 1);
    bool replaced = false;
    for (const std::string& a : env_add) replaced = replaced || a.rfind(name, 0) == 0;
    if (!replaced) env_s.push_back(entry);
  }
  env_s.insert(env_s.end(), env_add.begin(), env_add.end());
  std::vector<char*> envp;
  for (std::string& e : env_s) envp.push_back(e.data());
  envp.push_back(nullptr);
  const int out = ::open(stdout_path.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
  const int err = ::open(stderr_path.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
  const int null = ::open("/dev/null", O_RDONLY | O_CLOEXEC);
  if (out < 0 || err < 0 || null < 0) {
    ADD_FAILURE() << "cannot open the child's output files in " << stdout_path;
    for (int fd : {out, err, null})
      if (fd >= 0) ::close(fd);
    return false;
  }
  const pid_t parent = ::getpid();
  const pid_t pid = ::fork();
  if (pid == 0) {
    // The child dies with the test (the forking thread is the test's main
    // thread), so that a crashed test leaves no server behind.
    ::prctl(PR_SET_PDEATHSIG, SIGKILL);
    if (::getppid() != parent) ::_exit(127);
    ::dup2(null, STDIN_FILENO);
    ::dup2(out, STDOUT_FILENO);
    ::dup2(err, STDERR_FILENO);
    ::execve(argv[0], argv.data(), envp.data());
    ::_exit(127);
  }
  ::close(out);
  ::close(err);
  ::close(null);
  if (pid < 0) {
    ADD_FAILURE() << "fork: " << std::strerror(errno);
    return false;
  }
  pid_ = pid;
  signal_ = 0;
  return true;
}

bool ChildProcess::running() {
  if (pid_ <= 0) return false;
  int ws = 0;
  const pid_t r = ::waitpid(pid_, &ws, WNOHANG);
  if (r == 0) return true;
  // Reaped here: remember how it ended for wait().
  if (r == pid_) {
    exited_status_ = WIFEXITED(ws) ? WEXITSTATUS(ws) : -1;
    signal_ = WIFSIGNALED(ws) ? WTERMSIG(ws) : 0;
  }
  pid_ = -pid_;
  return false;
}

int ChildProcess::wait(Seconds timeout) {
  if (pid_ == 0) return -1;
  if (!wait_until([&] { return !running(); }, timeout)) return -1;
  return exited_status_;
}

void ChildProcess::send_signal(int sig) {
  if (pid_ > 0) ::kill(pid_, sig);
}

void ChildProcess::kill9() {
  if (pid_ > 0 && running()) {
    ::kill(pid_, SIGKILL);
    int ws = 0;
    while (::waitpid(pid_, &ws, 0) < 0 && errno == EINTR) {
    }
    exited_status_ = WIFEXITED(ws) ? WEXITSTATUS(ws) : -1;
    signal_ = WIFSIGNALED(ws) ? WTERMSIG(ws) : 0;
    pid_ = -pid_;
  }
}

ProcessResult run_program(const std::vector<std::string>& argv, const std::string& dir,
                          Seconds timeout) {
  static int counter = 0;
  const std::string base = dir + "/.run" + std::to_string(++counter);
  const std::string out = base + ".out", err = base + ".err";
  ProcessResult r;
  {
    ChildProcess child;
    if (!child.spawn(argv, out, err)) return r;
    r.status = child.wait(timeout);
    if (child.running()) {
      r.timed_out = true;
      child.kill9();
      ADD_FAILURE() << argv[0] << " did not end within " << timeout.count() << " s";
    }
    r.signal = child.signal();
  }
  r.out = slurp(out);
  r.err = slurp(err);
  std::error_code ec;
  fs::remove(out, ec);
  fs::remove(err, ec);
  return r;
}

// ---------------------------------------------------------------------------
// Api

Api::Api(std::shared_ptr<grpc::Channel> channel, std::string token)
    : channel_(std::move(channel)),
      stub_(v1::Visibility::NewStub(channel_)),
      token_(std::move(token)) {}

void Api::prepare(grpc::ClientContext* context, Seconds timeout) const {
  if (!token_.empty()) context->AddMetadata("authorization", "Bearer " + token_);
  context->set_deadline(std::chrono::system_clock::now() +
                        std::chrono::duration_cast<std::chrono::milliseconds>(timeout));
}

grpc::Status Api::create_scene(const std::string& id, const v1::SceneDescription& desc,
                               v1::SceneInfo* info) const {
  grpc::ClientContext ctx;
  prepare(&ctx);
  v1::CreateSceneRequest req;
  req.set_scene_id(id);
  *req.mutable_description() = desc;
  v1::SceneInfo resp;
  grpc::Status s = stub_->CreateScene(&ctx, req, &resp);
  if (info) *info = resp;
  return s;
}

grpc::Status Api::create_scene_json(const std::string& id, const std::string& json,
                                    v1::SceneInfo* info) const {
  grpc::ClientContext ctx;
  prepare(&ctx);
  v1::CreateSceneRequest req;
  req.set_scene_id(id);
  req.set_scene_json(json);
  v1::SceneInfo resp;
  grpc::Status s = stub_->CreateScene(&ctx, req, &resp);
  if (info) *info = resp;
  return s;
}

grpc::Status Api::delete_scene(const std::string& id) const {
  grpc::ClientContext ctx;
  prepare(&ctx);
  v1::DeleteSceneRequest req;
  req.set_scene_id(id);
  v1::DeleteSceneResponse resp;
  return stub_->DeleteScene(&ctx, req, &resp);
}

grpc::Status Api::list_scenes(std::vector<std::string>* ids) const {
  grpc::ClientContext ctx;
  prepare(&ctx);
  v1::ListScenesResponse resp;
  grpc::Status s = stub_->ListScenes(&ctx, v1::ListScenesRequest(), &resp);
  ids->clear();
  for (const v1::SceneInfo& i : resp.scenes()) ids->push_back(i.scene_id());
  return s;
}

grpc::Status Api::stats(const std::string& id, v1::SceneInfo* info) const {
  grpc::ClientContext ctx;
  prepare(&ctx);
  v1::GetSceneStatsRequest req;
  req.set_scene_id(id);
  return stub_->GetSceneStats(&ctx, req, info);
}

grpc::Status Api::export_scene(const std::string& id, v1::ExportSceneResponse* out) const {
  grpc::ClientContext ctx;
  prepare(&ctx);
  v1::ExportSceneRequest req;
  req.set_scene_id(id);
  return stub_->ExportScene(&ctx, req, out);
}

grpc::Status Api::get_pvs(const std::string& id, double t, const Camera& camera,
                          v1::GetPvsResponse* out) const {
  grpc::ClientContext ctx;
  prepare(&ctx);
  v1::GetPvsRequest req;
  req.set_scene_id(id);
  req.set_t(t);
  to_proto(camera, req.mutable_camera());
  return stub_->GetPvs(&ctx, req, out);
}

// ---------------------------------------------------------------------------
// ViewStream

ViewStream::ViewStream(const Api& api, std::string scene_id, v1::PvsEncoding encoding,
                       Seconds timeout)
    : scene_id_(std::move(scene_id)), encoding_(encoding) {
  api.prepare(&context_, timeout);
  stream_ = api.stub().View(&context_);
}

ViewStream::~ViewStream() {
  if (!finished_) {
    context_.TryCancel();
    stream_->Finish();
  }
}

bool ViewStream::send(std::uint64_t frame, double t, const Camera& camera) {
  v1::ViewRequest req;
  req.set_frame(frame);
  req.set_t(t);
  to_proto(camera, req.mutable_camera());
  return send(req);
}

bool ViewStream::send(const v1::ViewRequest& request) {
  if (first_) {
    first_ = false;
    v1::ViewRequest req = request;
    if (req.scene_id().empty()) req.set_scene_id(scene_id_);
    req.set_encoding(encoding_);
    return stream_->Write(req);
  }
  return stream_->Write(request);
}

bool ViewStream::read(v1::ViewResponse* response) { return stream_->Read(response); }

bool ViewStream::frame(std::uint64_t frame, double t, const Camera& camera,
                       v1::ViewResponse* response) {
  return send(frame, t, camera) && read(response);
}

bool ViewStream::writes_done() {
  if (writes_done_) return true;
  writes_done_ = true;
  return stream_->WritesDone();
}

grpc::Status ViewStream::finish() {
  if (finished_) return status_;
  writes_done();
  v1::ViewResponse r;
  while (stream_->Read(&r)) ++drained_;
  status_ = stream_->Finish();
  finished_ = true;
  return status_;
}

// ---------------------------------------------------------------------------
// SimStream

SimStream::SimStream(const Api& api, std::string scene_id, Seconds timeout)
    : scene_id_(std::move(scene_id)) {
  api.prepare(&context_, timeout);
  stream_ = api.stub().Simulate(&context_);
  v1::SimulateRequest first;
  first.set_scene_id(scene_id_);
  stream_->Write(first);
  reader_ = std::thread([this] { read_loop(); });
}

SimStream::~SimStream() {
  if (!finished_) {
    context_.TryCancel();
    if (reader_.joinable()) reader_.join();
    stream_->Finish();
  }
}

void SimStream::read_loop() {
  v1::SimulateResponse msg;
  while (stream_->Read(&msg)) {
    std::lock_guard<std::mutex> lock(mu_);
    if (msg.has_ack()) {
      acks_.push_back(msg.ack());
    } else if (msg.has_wake()) {
      const v1::WakeList& w = msg.wake();
      const std::string at = "wake list version " + std::to_string(w.version()) + ": ";
      auto ascending = [&](const google::protobuf::RepeatedField<std::uint32_t>& ids,
                           const char* name) {
        for (int i = 1; i < ids.size(); ++i)
          if (ids[i - 1] >= ids[i]) errors_.push_back(at + name + " not ascending");
      };
      if (w.full()) {
        ascending(w.ids(), "ids");
        wake_.assign(w.ids().begin(), w.ids().end());
      } else {
        if (history_.empty()) errors_.push_back(at + "the first wake list is not full");
        ascending(w.woken(), "woken");
        ascending(w.slept(), "slept");
        for (std::uint32_t id : w.slept()) {
          auto it = std::lower_bound(wake_.begin(), wake_.end(), id);
          if (it == wake_.end() || *it != id) {
            errors_.push_back(at + "slept id " + std::to_string(id) + " was not awake");
          } else {
            wake_.erase(it);
          }
        }
        for (std::uint32_t id : w.woken()) {
          auto it = std::lower_bound(wake_.begin(), wake_.end(), id);
          if (it != wake_.end() && *it == id) {
            errors_.push_back(at + "woken id " + std::to_string(id) + " was awake already");
          } else {
            wake_.insert(it, id);
          }
        }
      }
      if (!history_.empty() && w.version() <= version_)
        errors_.push_back(at + "not above the previous version " + std::to_string(version_));
      version_ = w.version();
      if (w.size() != wake_.size())
        errors_.push_back(at + "size " + std::to_string(w.size()) + " but " +
                          std::to_string(wake_.size()) + " ids after reassembly");
      history_.push_back(wake_);
    } else {
      errors_.push_back("a SimulateResponse with neither ack nor wake");
    }
    cv_.notify_all();
  }
  std::lock_guard<std::mutex> lock(mu_);
  ended_ = true;
  cv_.notify_all();
}

bool SimStream::send(std::uint64_t seq, double t, const std::vector<Move>& moves) {
  v1::SimulateRequest req;
  v1::MoveBatch* b = req.mutable_batch();
  b->set_seq(seq);
  b->set_t(t);
  for (const Move& m : moves) to_proto(m, b->add_moves());
  return stream_->Write(req);
}

bool SimStream::wait_ack(v1::MoveAck* ack, Seconds timeout) {
  std::unique_lock<std::mutex> lock(mu_);
  if (!cv_.wait_for(lock, timeout, [&] { return !acks_.empty() || ended_; })) return false;
  if (acks_.empty()) return false;
  *ack = acks_.front();
  acks_.pop_front();
  return true;
}

bool SimStream::move(std::uint64_t seq, double t, const std::vector<Move>& moves,
                     v1::MoveAck* ack) {
  return send(seq, t, moves) && wait_ack(ack);
}

std::vector<std::vector<ObjectId>> SimStream::wake_history() const {
  std::lock_guard<std::mutex> lock(mu_);
  return history_;
}

bool SimStream::wait_wake_count(std::size_t count, Seconds timeout) {
  std::unique_lock<std::mutex> lock(mu_);
  cv_.wait_for(lock, timeout, [&] { return history_.size() > count || ended_; });
  return history_.size() > count;
}

std::vector<std::string> SimStream::protocol_errors() const {
  std::lock_guard<std::mutex> lock(mu_);
  return errors_;
}

bool SimStream::ended() const {
  std::lock_guard<std::mutex> lock(mu_);
  return ended_;
}

grpc::Status SimStream::finish() {
  if (finished_) return status_;
  if (!writes_done_) {
    writes_done_ = true;
    stream_->WritesDone();
  }
  if (reader_.joinable()) reader_.join();
  status_ = stream_->Finish();
  finished_ = true;
  return status_;
}

// ---------------------------------------------------------------------------
// ServerProcess

ServerProcess::ServerProcess(std::vector<std::string> extra_args)
    : extra_args_(std::move(extra_args)), dir_(make_temp_dir("voxvis-server-test")) {}

ServerProcess::~ServerProcess() {
  if (child_) child_->kill9();
  if (::testing::Test::HasFailure()) {
    std::string text = log();
    constexpr std::size_t kMax = 16000;
    if (text.size() > kMax) text = "...\n" + text.substr(text.size() - kMax);
    std::cerr << "---- voxvis-server stderr (" << dir_ << ") ----\n"
              << text << "---- end of voxvis-server stderr ----\n";
  }
  if (!dir_.empty() && std::getenv("VOXVIS_KEEP_TEST_DIRS") == nullptr) {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
}

::testing::AssertionResult ServerProcess::start() {
  if (dir_.empty()) return ::testing::AssertionFailure() << "no temporary directory";
  if (running()) return ::testing::AssertionFailure() << "the server is running already";
  const std::string port_file = path("port");
  std::error_code ec;
  fs::remove(port_file, ec);
  // VOXVIS_TEST_SERVER runs the tests against another build (a mutation
  // check, or the previous release).
  const char* other = std::getenv("VOXVIS_TEST_SERVER");
  const std::string binary = other != nullptr && *other != '\0' ? other : VOXVIS_SERVER;
  std::vector<std::string> argv = {binary,    "--listen",   "127.0.0.1:0", "--port-file",
                                   port_file, "--data-dir", data_dir()};
  argv.insert(argv.end(), extra_args_.begin(), extra_args_.end());
  child_ = std::make_unique<ChildProcess>();
  const std::string log_path = path("server.log");
  if (!child_->spawn(argv, log_path, log_path, extra_env_))
    return ::testing::AssertionFailure() << "cannot start " << binary;
  port_ = 0;
  const bool up = wait_until(
      [&] {
        if (!child_->running()) return true;
        const std::string text = slurp(port_file);
        if (!text.empty() && text.back() == '\n') port_ = std::atoi(text.c_str());
        return port_ > 0;
      },
      Seconds(20));
  if (port_ > 0) return ::testing::AssertionSuccess();
  if (!child_->running()) {
    const int status = child_->wait(Seconds(1));
    return ::testing::AssertionFailure() << "voxvis-server exited (status " << status << ", signal "
                                         << child_->signal() << ") before serving:\n"
                                         << log();
  }
  (void)up;
  child_->kill9();
  return ::testing::AssertionFailure() << "voxvis-server wrote no port file within 20 s:\n"
                                       << log();
}

std::shared_ptr<grpc::Channel> ServerProcess::channel(
    const std::vector<std::pair<std::string, int>>& int_args) const {
  grpc::ChannelArguments args;
  // Each channel gets its own connection, as separate clients would.
  args.SetInt(GRPC_ARG_USE_LOCAL_SUBCHANNEL_POOL, 1);
  args.SetMaxReceiveMessageSize(64 << 20);
  for (const auto& [key, value] : int_args) args.SetInt(key, value);
  return grpc::CreateCustomChannel(address(), grpc::InsecureChannelCredentials(), args);
}

Api ServerProcess::api(const std::string& token) const { return Api(channel(), token); }

int ServerProcess::terminate(Seconds timeout) {
  signal(SIGTERM);
  return wait_exit(timeout);
}

void ServerProcess::signal(int sig) {
  if (child_) child_->send_signal(sig);
}

int ServerProcess::wait_exit(Seconds timeout) {
  if (!child_) return -1;
  const int status = child_->wait(timeout);
  if (child_->running()) {
    ADD_FAILURE() << "voxvis-server still running after " << timeout.count() << " s";
    child_->kill9();
    return -1;
  }
  return status;
}

void ServerProcess::kill9() {
  if (child_) child_->kill9();
}

namespace {

/// A "Name:   123 kB" line of /proc/PID/status, KiB; -1 when absent.
long proc_status_kib(pid_t pid, const std::string& name) {
  if (pid <= 0) return -1;
  std::ifstream in("/proc/" + std::to_string(pid) + "/status");
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind(name + ":", 0) == 0) return std::atol(line.c_str() + name.size() + 1);
  }
  return -1;
}

}  // namespace

long ServerProcess::peak_rss_kib() const { return proc_status_kib(pid(), "VmHWM"); }

long ServerProcess::rss_kib() const { return proc_status_kib(pid(), "VmRSS"); }

bool ServerProcess::reset_peak_rss() const {
  if (pid() <= 0) return false;
  std::FILE* f = std::fopen(("/proc/" + std::to_string(pid()) + "/clear_refs").c_str(), "w");
  if (f == nullptr) return false;
  const bool written = std::fputs("5", f) >= 0;
  return std::fclose(f) == 0 && written;
}

double ServerProcess::cpu_seconds() const {
  if (pid() <= 0) return -1.0;
  // /proc/PID/stat: the command name is in parentheses and may hold spaces;
  // utime and stime are the 14th and 15th fields, in clock ticks.
  const std::string stat = slurp("/proc/" + std::to_string(pid()) + "/stat");
  const std::size_t close = stat.rfind(')');
  if (close == std::string::npos) return -1.0;
  std::istringstream in(stat.substr(close + 2));
  std::string field;
  double ticks = 0.0;
  for (int i = 3; i <= 15 && in >> field; ++i)
    if (i >= 14) ticks += std::stod(field);
  return ticks / static_cast<double>(sysconf(_SC_CLK_TCK));
}

std::string ServerProcess::log() const { return slurp(dir_ + "/server.log"); }

int ServerProcess::metrics_port() const {
  const std::string text = log();
  const std::string marker = "/metrics\n";
  const std::size_t at = text.find("metrics at http://");
  if (at == std::string::npos) return 0;
  const std::size_t end = text.find(marker, at);
  return end == std::string::npos ? 0 : static_cast<int>(number_before(text.substr(at), marker));
}

std::string show(const grpc::Status& s) {
  return std::to_string(static_cast<int>(s.error_code())) + " " + s.error_message();
}

long number_before(const std::string& text, const std::string& marker) {
  const std::size_t end = text.find(marker);
  if (end == std::string::npos) return -1;
  std::size_t begin = end;
  while (begin > 0 && std::isdigit(static_cast<unsigned char>(text[begin - 1]))) --begin;
  return begin == end ? -1 : std::stol(text.substr(begin, end - begin));
}

::testing::AssertionResult make_test_certificate(const std::string& cert, const std::string& key,
                                                 const std::string& dir) {
  const ProcessResult made = run_program(
      {"/usr/bin/openssl", "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-days", "2", "-subj",
       "/CN=voxvis.test", "-addext", "subjectAltName=DNS:voxvis.test", "-keyout", key, "-out", cert},
      dir);
  if (made.status == 0) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << "openssl failed: " << made.err;
}

// ---------------------------------------------------------------------------
// PvsFlood and http_get

PvsFlood::PvsFlood(const Api& api, const std::string& scene_id, int count, double t,
                   const Camera& camera, Seconds timeout) {
  calls_.reserve(static_cast<std::size_t>(count));
  for (int i = 0; i < count; ++i) {
    auto call = std::make_unique<Call>();
    api.prepare(&call->context, timeout);
    call->request.set_scene_id(scene_id);
    call->request.set_t(t);
    to_proto(camera, call->request.mutable_camera());
    calls_.push_back(std::move(call));
  }
  // Every call is built before the first is sent: the callbacks only touch
  // the counters.
  for (auto& call : calls_) {
    api.stub().async()->GetPvs(&call->context, &call->request, &call->response,
                               [this](grpc::Status status) {
                                 std::lock_guard<std::mutex> lock(mu_);
                                 ++done_;
                                 ++codes_[status.error_code()];
                                 cv_.notify_all();
                               });
  }
}

PvsFlood::~PvsFlood() {
  if (!wait_all(Seconds(60))) {
    cancel();
    wait_all(Seconds(600));
  }
}

int PvsFlood::done() const {
  std::lock_guard<std::mutex> lock(mu_);
  return done_;
}

int PvsFlood::with_code(grpc::StatusCode code) const {
  std::lock_guard<std::mutex> lock(mu_);
  const auto it = codes_.find(code);
  return it == codes_.end() ? 0 : it->second;
}

bool PvsFlood::wait_all(Seconds timeout) const {
  std::unique_lock<std::mutex> lock(mu_);
  return cv_.wait_for(lock, timeout, [this] { return done_ == static_cast<int>(calls_.size()); });
}

void PvsFlood::cancel() {
  for (auto& call : calls_) call->context.TryCancel();
}

std::string http_get(int port, const std::string& path) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  if (fd < 0) return "socket failed";
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<std::uint16_t>(port));
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (::connect(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof addr) != 0) {
    ::close(fd);
    return "connect failed";
  }
  // HTTP/1.0: the server closes the connection after the answer, so reading
  // to EOF gets all of it.
  const std::string request = "GET " + path + " HTTP/1.0\r\nHost: 127.0.0.1\r\n\r\n";
  if (::send(fd, request.data(), request.size(), 0) != static_cast<ssize_t>(request.size())) {
    ::close(fd);
    return "send failed";
  }
  std::string response;
  char buffer[4096];
  for (;;) {
    const ssize_t n = ::recv(fd, buffer, sizeof buffer, 0);
    if (n <= 0) break;
    response.append(buffer, static_cast<std::size_t>(n));
  }
  ::close(fd);
  return response;
}

// ---------------------------------------------------------------------------
// Generic calls

namespace {

grpc::ByteBuffer to_buffer(const std::string& bytes) {
  grpc::Slice slice(bytes);
  return grpc::ByteBuffer(&slice, 1);
}

std::string from_buffer(const grpc::ByteBuffer& buffer) {
  std::vector<grpc::Slice> slices;
  std::string out;
  if (!buffer.Dump(&slices).ok()) return out;
  for (const grpc::Slice& s : slices)
    out.append(reinterpret_cast<const char*>(s.begin()), s.size());
  return out;
}

/// Waits for the next completion of `cq` (bounded by the call's deadline);
/// true when it is `tag` and succeeded.
bool next_is(grpc::CompletionQueue& cq, void* tag) {
  void* got = nullptr;
  bool ok = false;
  if (!cq.Next(&got, &ok)) return false;
  return got == tag && ok;
}

void drain(grpc::CompletionQueue& cq) {
  cq.Shutdown();
  void* tag = nullptr;
  bool ok = false;
  while (cq.Next(&tag, &ok)) {
  }
}

}  // namespace

grpc::Status generic_unary(const std::shared_ptr<grpc::Channel>& channel, const std::string& method,
                           const std::string& request, std::string* response, Seconds timeout,
                           const std::string& token) {
  grpc::GenericStub stub(channel);
  grpc::ClientContext ctx;
  if (!token.empty()) ctx.AddMetadata("authorization", "Bearer " + token);
  ctx.set_deadline(std::chrono::system_clock::now() +
                   std::chrono::duration_cast<std::chrono::milliseconds>(timeout));
  grpc::CompletionQueue cq;
  grpc::Status status(grpc::StatusCode::UNKNOWN, "no completion");
  grpc::ByteBuffer resp;
  {
    std::unique_ptr<grpc::GenericClientAsyncResponseReader> call =
        stub.PrepareUnaryCall(&ctx, method, to_buffer(request), &cq);
    call->StartCall();
    int tag = 0;
    call->Finish(&resp, &status, &tag);
    void* got = nullptr;
    bool ok = false;
    cq.Next(&got, &ok);
  }
  drain(cq);
  *response = from_buffer(resp);
  return status;
}

grpc::Status generic_bidi(const std::shared_ptr<grpc::Channel>& channel, const std::string& method,
                          const std::string& request, std::vector<std::string>* responses,
                          Seconds timeout, const std::string& token) {
  grpc::GenericStub stub(channel);
  grpc::ClientContext ctx;
  if (!token.empty()) ctx.AddMetadata("authorization", "Bearer " + token);
  ctx.set_deadline(std::chrono::system_clock::now() +
                   std::chrono::duration_cast<std::chrono::milliseconds>(timeout));
  grpc::CompletionQueue cq;
  grpc::Status status(grpc::StatusCode::UNKNOWN, "no completion");
  {
    std::unique_ptr<grpc::GenericClientAsyncReaderWriter> call =
        stub.PrepareCall(&ctx, method, &cq);
    int start = 0, write = 0, done = 0, read = 0, finish = 0;
    call->StartCall(&start);
    if (next_is(cq, &start)) {
      call->Write(to_buffer(request), &write);
      if (next_is(cq, &write)) {
        call->WritesDone(&done);
        if (next_is(cq, &done)) {
          grpc::ByteBuffer buffer;
          for (;;) {
            call->Read(&buffer, &read);
            if (!next_is(cq, &read)) break;
            responses->push_back(from_buffer(buffer));
          }
        }
      }
    }
    call->Finish(&status, &finish);
    void* got = nullptr;
    bool ok = false;
    while (cq.Next(&got, &ok) && got != &finish) {
    }
  }
  drain(cq);
  return status;
}

// ---------------------------------------------------------------------------
// Scenes, cameras and conversions

std::vector<ObjectId> ids_of(const google::protobuf::RepeatedField<std::uint32_t>& ids) {
  return std::vector<ObjectId>(ids.begin(), ids.end());
}

namespace {
std::string counters_of(std::uint64_t voxels, std::uint32_t shells, std::uint32_t disc,
                        std::uint32_t created, std::uint32_t revealed, std::uint32_t expired,
                        std::uint32_t active, std::uint32_t violations, std::uint32_t outside,
                        std::uint32_t pvs, bool early) {
  std::ostringstream o;
  o << "voxels_visited=" << voxels << " shells=" << shells << " objects_discretized=" << disc
    << " tbvs_created=" << created << " tbvs_revealed=" << revealed << " tbvs_expired=" << expired
    << " tbvs_active=" << active << " speed_violations=" << violations
    << " outside_tested=" << outside << " pvs_size=" << pvs << " early_exit=" << early;
  return o.str();
}
}  // namespace

std::string counters(const FrameStats& s) {
  return counters_of(s.voxels_visited, s.shells, s.objects_discretized, s.tbvs_created,
                     s.tbvs_revealed, s.tbvs_expired, s.tbvs_active, s.speed_violations,
                     s.outside_tested, s.pvs_size, s.early_exit);
}

std::string counters(const v1::FrameStats& s) {
  return counters_of(s.voxels_visited(), s.shells(), s.objects_discretized(), s.tbvs_created(),
                     s.tbvs_revealed(), s.tbvs_expired(), s.tbvs_active(), s.speed_violations(),
                     s.outside_tested(), s.pvs_size(), s.early_exit());
}

Camera look(Vec3 eye, Vec3 dir) {
  Camera c;
  c.eye = eye;
  c.dir = dir;
  c.up = Vec3(0, 1, 0);
  c.fov_y_deg = 60;
  c.aspect = 1.5;
  c.near = 0.05;
  c.far = 1000;
  return c;
}

grpc::Status create_with_deadline(const Api& api, const std::string& id, const v1::SceneDescription& d,
                                  Seconds timeout) {
  grpc::ClientContext ctx;
  api.prepare(&ctx, timeout);
  v1::CreateSceneRequest req;
  req.set_scene_id(id);
  *req.mutable_description() = d;
  v1::SceneInfo info;
  return api.stub().CreateScene(&ctx, req, &info);
}

std::string wall_scene_json() {
  return R"({
  "format": "voxvis-scene/1",
  "bounds": {"min": [0, 0, 0], "max": [20, 20, 20]},
  "grid": [20, 20, 20],
  "objects": [
    {"id": 1, "shape": "box", "min": [0, 0, 8.5], "max": [20, 20, 11.5]},
    {"id": 2, "shape": "sphere", "center": [10, 10, 15], "radius": 1, "dynamic": true, "max_speed": 100},
    {"id": 3, "shape": "sphere", "center": [10, 10, 5], "radius": 1}
  ]
}
)";
}

Camera wall_camera() { return look(Vec3(10, 10, 1), Vec3(0, 0, 1)); }

SceneDesc huge_footprint_scene(int count) {
  SceneDesc d;
  d.bounds_min = Vec3(-1e12);
  d.bounds_max = Vec3(1e12);
  Rng rng(0x5e1f);
  for (int i = 0; i < count; ++i) {
    ObjectDesc o;
    o.id = static_cast<ObjectId>(i + 1);
    o.shape = Shape::Sphere;
    o.center = Vec3(rng.uniform(-1e12, 1e12), rng.uniform(-1e12, 1e12), rng.uniform(-1e12, 1e12));
    o.radius = 1e12;
    d.objects.push_back(o);
  }
  return d;
}

SceneDesc lattice_scene(int count, int grid, std::uint64_t seed) {
  test::Rng rng(seed);
  SceneDesc d;
  d.bounds_min = Vec3(0.0);
  d.bounds_max = Vec3(100.0);
  d.grid = glm::ivec3(grid);
  int side = 1;
  while (side * side * side < count) ++side;
  const double step = 100.0 / side;
  for (int i = 0; i < count; ++i) {
    const int x = i % side, y = (i / side) % side, z = i / (side * side);
    ObjectDesc o;
    o.id = static_cast<ObjectId>(i + 1);
    o.shape = Shape::Sphere;
    o.center = Vec3((x + rng.uniform(0.3, 0.7)) * step, (y + rng.uniform(0.3, 0.7)) * step,
                    (z + rng.uniform(0.3, 0.7)) * step);
    o.radius = step * 0.1;
    if (i % 5 == 0) {
      o.dynamic = true;
      o.max_speed = 5.0;
    }
    d.objects.push_back(o);
  }
  return d;
}

/// Compares two output files of `voxvis replay` format: every line's frame,
/// pvs, wake and every stats counter but the times (time_us and its split).
void expect_same_output(const std::string& expected_text, const std::string& actual_text,
                        const std::string& what) {
  const std::vector<std::string> expected = lines_of(expected_text);
  const std::vector<std::string> actual = lines_of(actual_text);
  ASSERT_EQ(actual.size(), expected.size()) << what;
  for (std::size_t i = 0; i < expected.size(); ++i) {
    SCOPED_TRACE(what + ", line " + std::to_string(i + 1));
    const nlohmann::json e = nlohmann::json::parse(expected[i], nullptr, false);
    const nlohmann::json a = nlohmann::json::parse(actual[i], nullptr, false);
    ASSERT_FALSE(e.is_discarded()) << expected[i];
    ASSERT_FALSE(a.is_discarded()) << actual[i];
    EXPECT_EQ(a.at("frame"), e.at("frame"));
    EXPECT_EQ(a.at("pvs"), e.at("pvs"));
    EXPECT_EQ(a.at("wake"), e.at("wake"));
    nlohmann::json es = e.at("stats"), as = a.at("stats");
    for (const char* timing : {"time_us", "traverse_us", "render_us", "retest_us"}) {
      ASSERT_TRUE(es.contains(timing)) << timing;
      ASSERT_TRUE(as.contains(timing)) << timing;
      es.erase(timing);
      as.erase(timing);
    }
    EXPECT_EQ(as, es);
  }
}

}  // namespace voxvis::servertest
