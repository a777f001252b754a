// client.cpp — voxvis::client: channel setup, conversions, unary calls and the
// lock-step View and Simulate sessions (voxvis/client.h).
#include "voxvis/client.h"

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <sstream>
#include <unordered_map>
#include <utility>

namespace voxvis::client {

// ---------------------------------------------------------------------------
// Connection

bool read_whole(const std::string& path, std::string* text, std::string* error) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    *error = std::string("cannot open: ") + std::strerror(errno);
    return false;
  }
  std::ostringstream buf;
  buf << in.rdbuf();
  if (in.bad()) {
    *error = std::string("cannot read: ") + std::strerror(errno);
    return false;
  }
  *text = std::move(buf).str();
  return true;
}

std::shared_ptr<grpc::Channel> connect(const ConnectOptions& options, std::string* error) {
  if (options.address.empty()) {
    *error = "--server: the server address is empty (expected HOST:PORT)";
    return nullptr;
  }
  if (options.max_message_bytes <= 0) {
    *error = "max_message_bytes: must be > 0, got " + std::to_string(options.max_message_bytes);
    return nullptr;
  }
  grpc::ChannelArguments args;
  args.SetMaxReceiveMessageSize(options.max_message_bytes);
  args.SetMaxSendMessageSize(options.max_message_bytes);
  if (options.channel_index != 0) args.SetInt("voxvis.channel_index", options.channel_index);

  std::shared_ptr<grpc::ChannelCredentials> credentials;
  if (options.tls_ca_file.empty()) {
    if (!options.tls_server_name.empty()) {
      *error = "--tls-server-name: only applies with TLS (--tls-ca FILE)";
      return nullptr;
    }
    credentials = grpc::InsecureChannelCredentials();
  } else {
    grpc::SslCredentialsOptions ssl;
    if (!read_whole(options.tls_ca_file, &ssl.pem_root_certs, error)) {
      *error = options.tls_ca_file + ": " + *error;
      return nullptr;
    }
    if (ssl.pem_root_certs.find("-----BEGIN CERTIFICATE-----") == std::string::npos) {
      *error = options.tls_ca_file + ": no PEM certificate in the file (expected -----BEGIN CERTIFICATE-----)";
      return nullptr;
    }
    credentials = grpc::SslCredentials(ssl);
    if (!options.tls_server_name.empty()) args.SetSslTargetNameOverride(options.tls_server_name);
  }
  std::shared_ptr<grpc::Channel> channel =
      grpc::CreateCustomChannel(options.address, credentials, args);
  if (channel == nullptr) *error = "cannot create a channel to " + options.address;
  return channel;
}

bool load_token(const std::string& path, std::string* token, std::string* error) {
  std::string text;
  if (!read_whole(path, &text, error)) {
    *error = path + ": " + *error;
    return false;
  }
  std::istringstream in(text);
  std::string line;
  int line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    const std::size_t begin = line.find_first_not_of(" \t\r");
    if (begin == std::string::npos || line[begin] == '#') continue;
    const std::size_t end = line.find_last_not_of(" \t\r");
    std::string value = line.substr(begin, end - begin + 1);
    for (const char c : value) {
      const auto u = static_cast<unsigned char>(c);
      if (u <= 0x20 || u >= 0x7f) {
        *error = path + ":" + std::to_string(line_no) +
                 ": a token must be one word of printable ASCII characters (no white space)";
        return false;
      }
    }
    *token = std::move(value);
    return true;
  }
  *error = path + ": no token in the file (expected one line with the token; '#' starts a comment)";
  return false;
}

void add_token(grpc::ClientContext* context, const std::string& token) {
  if (!token.empty()) context->AddMetadata("authorization", "Bearer " + token);
}

const char* status_code_name(grpc::StatusCode code) {
  switch (code) {
    case grpc::StatusCode::OK: return "OK";
    case grpc::StatusCode::CANCELLED: return "CANCELLED";
    case grpc::StatusCode::UNKNOWN: return "UNKNOWN";
    case grpc::StatusCode::INVALID_ARGUMENT: return "INVALID_ARGUMENT";
    case grpc::StatusCode::DEADLINE_EXCEEDED: return "DEADLINE_EXCEEDED";
    case grpc::StatusCode::NOT_FOUND: return "NOT_FOUND";
    case grpc::StatusCode::ALREADY_EXISTS: return "ALREADY_EXISTS";
    case grpc::StatusCode::PERMISSION_DENIED: return "PERMISSION_DENIED";
    case grpc::StatusCode::RESOURCE_EXHAUSTED: return "RESOURCE_EXHAUSTED";
    case grpc::StatusCode::FAILED_PRECONDITION: return "FAILED_PRECONDITION";
    case grpc::StatusCode::ABORTED: return "ABORTED";
    case grpc::StatusCode::OUT_OF_RANGE: return "OUT_OF_RANGE";
    case grpc::StatusCode::UNIMPLEMENTED: return "UNIMPLEMENTED";
    case grpc::StatusCode::INTERNAL: return "INTERNAL";
    case grpc::StatusCode::UNAVAILABLE: return "UNAVAILABLE";
    case grpc::StatusCode::DATA_LOSS: return "DATA_LOSS";
    case grpc::StatusCode::UNAUTHENTICATED: return "UNAUTHENTICATED";
    default: return "UNKNOWN_CODE";
  }
}

std::string describe(const grpc::Status& status, const std::string& address) {
  if (status.error_code() == grpc::StatusCode::UNAVAILABLE && !address.empty()) {
    return "cannot reach server at " + address + " (UNAVAILABLE: " + status.error_message() + ")";
  }
  return std::string("server: ") + status_code_name(status.error_code()) + ": " +
         status.error_message();
}

// ---------------------------------------------------------------------------
// Conversions

void to_proto(const Vec3& v, v1::Vec3* out) {
  out->set_x(v.x);
  out->set_y(v.y);
  out->set_z(v.z);
}

Vec3 from_proto(const v1::Vec3& v) { return Vec3(v.x(), v.y(), v.z()); }

void to_proto(const SceneDesc& scene, v1::SceneDescription* out) {
  out->Clear();
  to_proto(scene.bounds_min, out->mutable_bounds_min());
  to_proto(scene.bounds_max, out->mutable_bounds_max());
  if (scene.grid) {
    // Engine resolutions are >= 1 once validated; a negative one becomes a
    // huge value the server refuses, never a silently accepted one.
    out->mutable_grid()->set_nx(static_cast<std::uint32_t>(scene.grid->x));
    out->mutable_grid()->set_ny(static_cast<std::uint32_t>(scene.grid->y));
    out->mutable_grid()->set_nz(static_cast<std::uint32_t>(scene.grid->z));
  }
  out->mutable_objects()->Reserve(static_cast<int>(scene.objects.size()));
  // Each mesh goes once into the table, in the order objects first name it;
  // the objects that share it (one shared_ptr) name one entry.
  std::unordered_map<const Mesh*, std::uint32_t> mesh_index;
  for (const ObjectDesc& o : scene.objects) {
    v1::Object* p = out->add_objects();
    p->set_id(o.id);
    if (o.shape == Shape::Mesh) {
      // A mesh object without its mesh (not a valid description) is sent
      // without a shape, which the server refuses naming the object.
      if (o.mesh) {
        const auto [at, added] = mesh_index.emplace(o.mesh.get(), static_cast<std::uint32_t>(out->meshes_size()));
        if (added) to_proto(*o.mesh, out->add_meshes());
        v1::MeshInstance* m = p->mutable_mesh();
        m->set_index(at->second);
        to_proto(o.center, m->mutable_center());
        to_proto(o.rotation, m->mutable_rotation());
        m->set_scale(o.scale);
      }
    } else if (o.shape == Shape::Sphere) {
      to_proto(o.center, p->mutable_sphere()->mutable_center());
      p->mutable_sphere()->set_radius(o.radius);
    } else if (o.shape == Shape::Box) {
      to_proto(o.center - o.half_extent, p->mutable_box()->mutable_min());
      to_proto(o.center + o.half_extent, p->mutable_box()->mutable_max());
    }
    p->set_dynamic(o.dynamic);
    if (o.dynamic) p->set_max_speed(o.max_speed);
  }
}

void to_proto(const Quat& q, v1::Quat* out) {
  out->set_w(q.w);
  out->set_x(q.x);
  out->set_y(q.y);
  out->set_z(q.z);
}

Quat from_proto(const v1::Quat& q) { return Quat(q.w(), q.x(), q.y(), q.z()); }

void to_proto(const Mesh& mesh, v1::Mesh* out) {
  out->Clear();
  auto* v = out->mutable_vertices();
  v->Reserve(static_cast<int>(3 * mesh.vertices.size()));
  for (const Vec3& p : mesh.vertices) {
    v->AddAlreadyReserved(p.x);
    v->AddAlreadyReserved(p.y);
    v->AddAlreadyReserved(p.z);
  }
  auto* t = out->mutable_triangles();
  t->Reserve(static_cast<int>(3 * mesh.triangles.size()));
  for (const auto& tri : mesh.triangles)
    for (std::uint32_t i : tri) t->AddAlreadyReserved(i);
}

void to_proto(const Move& move, v1::Move* out) {
  out->set_id(move.id);
  to_proto(move.center, out->mutable_center());
  if (move.has_rotation) {
    to_proto(move.rotation, out->mutable_rotation());
  } else {
    out->clear_rotation();
  }
}

Move from_proto(const v1::Move& move) {
  Move m;
  m.id = move.id();
  m.center = from_proto(move.center());
  m.has_rotation = move.has_rotation();
  if (m.has_rotation) m.rotation = from_proto(move.rotation());
  return m;
}

void to_proto(const Camera& camera, v1::Camera* out) {
  to_proto(camera.eye, out->mutable_eye());
  to_proto(camera.dir, out->mutable_dir());
  to_proto(camera.up, out->mutable_up());
  out->set_fov_y_deg(camera.fov_y_deg);
  out->set_aspect(camera.aspect);
  out->set_near(camera.near);
  out->set_far(camera.far);
  if (camera.eye_extent != Vec3(0.0)) to_proto(camera.eye_extent, out->mutable_eye_extent());
  out->set_omnidirectional(camera.omnidirectional);
  out->set_horizon_s(camera.horizon_s);
}

Camera from_proto(const v1::Camera& camera) {
  Camera c;
  c.eye = from_proto(camera.eye());
  c.dir = from_proto(camera.dir());
  c.up = from_proto(camera.up());
  c.fov_y_deg = camera.fov_y_deg();
  c.aspect = camera.aspect();
  c.near = camera.near();
  c.far = camera.far();
  if (camera.has_eye_extent()) c.eye_extent = from_proto(camera.eye_extent());
  c.omnidirectional = camera.omnidirectional();
  c.horizon_s = camera.horizon_s();
  return c;
}

FrameStats from_proto(const v1::FrameStats& stats) {
  FrameStats s;
  s.time_us = stats.time_us();
  s.voxels_visited = stats.voxels_visited();
  s.shells = stats.shells();
  s.objects_discretized = stats.objects_discretized();
  s.tbvs_created = stats.tbvs_created();
  s.tbvs_revealed = stats.tbvs_revealed();
  s.tbvs_expired = stats.tbvs_expired();
  s.tbvs_active = stats.tbvs_active();
  s.speed_violations = stats.speed_violations();
  s.outside_tested = stats.outside_tested();
  s.pvs_size = stats.pvs_size();
  s.early_exit = stats.early_exit();
  s.front_voxels_culled = stats.front_voxels_culled();
  s.front_objects_culled = stats.front_objects_culled();
  s.ob_width = stats.ob_width();
  s.ob_voxels_culled = stats.ob_voxels_culled();
  s.ob_objects_culled = stats.ob_objects_culled();
  s.ob_occluders = stats.ob_occluders();
  s.frustum_fallback = stats.frustum_fallback();
  s.region = stats.region();
  s.ob_pixels_written = stats.ob_pixels_written();
  s.cells_visited = stats.cells_visited();
  s.cells_hidden = stats.cells_hidden();
  s.cells_whole = stats.cells_whole();
  s.traverse_us = stats.traverse_us();
  s.render_us = stats.render_us();
  s.retest_us = stats.retest_us();
  return s;
}

// ---------------------------------------------------------------------------
// Unary calls

Client::Client(std::shared_ptr<grpc::Channel> channel, std::string token, std::string address)
    : channel_(std::move(channel)),
      stub_(v1::Visibility::NewStub(channel_)),
      token_(std::move(token)),
      address_(std::move(address)) {}

void Client::prepare(grpc::ClientContext* context, std::chrono::milliseconds timeout) const {
  add_token(context, token_);
  context->set_wait_for_ready(false);
  if (timeout.count() > 0) context->set_deadline(std::chrono::system_clock::now() + timeout);
}

grpc::Status Client::create_scene(const std::string& scene_id, const std::string& scene_json,
                                  v1::SceneInfo* info) const {
  grpc::ClientContext context;
  prepare(&context, create_timeout);
  v1::CreateSceneRequest request;
  request.set_scene_id(scene_id);
  request.set_scene_json(scene_json);
  return stub_->CreateScene(&context, request, info);
}

grpc::Status Client::create_scene(const std::string& scene_id, const std::string& scene_json,
                                  const v1::ScenePositions* positions, v1::SceneInfo* info) const {
  grpc::ClientContext context;
  prepare(&context, create_timeout);
  v1::CreateSceneRequest request;
  request.set_scene_id(scene_id);
  request.set_scene_json(scene_json);
  if (positions) *request.mutable_positions() = *positions;
  return stub_->CreateScene(&context, request, info);
}

grpc::Status Client::create_scene(const std::string& scene_id, const SceneDesc& scene,
                                  v1::SceneInfo* info) const {
  grpc::ClientContext context;
  prepare(&context, create_timeout);
  v1::CreateSceneRequest request;
  request.set_scene_id(scene_id);
  to_proto(scene, request.mutable_description());
  return stub_->CreateScene(&context, request, info);
}

grpc::Status Client::delete_scene(const std::string& scene_id, bool only_if_misplaced) const {
  grpc::ClientContext context;
  prepare(&context, call_timeout);
  v1::DeleteSceneRequest request;
  request.set_scene_id(scene_id);
  request.set_only_if_misplaced(only_if_misplaced);
  v1::DeleteSceneResponse response;
  return stub_->DeleteScene(&context, request, &response);
}

grpc::Status Client::list_scenes(std::vector<v1::SceneInfo>* scenes) const {
  grpc::ClientContext context;
  prepare(&context, call_timeout);
  v1::ListScenesResponse response;
  const grpc::Status status = stub_->ListScenes(&context, v1::ListScenesRequest{}, &response);
  scenes->clear();
  if (status.ok()) {
    scenes->assign(std::make_move_iterator(response.mutable_scenes()->begin()),
                   std::make_move_iterator(response.mutable_scenes()->end()));
  }
  return status;
}

grpc::Status Client::list_scenes(v1::ListScenesResponse* response) const {
  grpc::ClientContext context;
  prepare(&context, call_timeout);
  return stub_->ListScenes(&context, v1::ListScenesRequest{}, response);
}

grpc::Status Client::export_scene(const std::string& scene_id, v1::ExportSceneResponse* response,
                                  bool only_if_misplaced) const {
  grpc::ClientContext context;
  prepare(&context, create_timeout);
  v1::ExportSceneRequest request;
  request.set_scene_id(scene_id);
  request.set_only_if_misplaced(only_if_misplaced);
  return stub_->ExportScene(&context, request, response);
}

grpc::Status Client::get_scene_stats(const std::string& scene_id, v1::SceneInfo* info) const {
  grpc::ClientContext context;
  prepare(&context, call_timeout);
  v1::GetSceneStatsRequest request;
  request.set_scene_id(scene_id);
  return stub_->GetSceneStats(&context, request, info);
}

grpc::Status Client::get_pvs(const std::string& scene_id, double t, const Camera& camera,
                             FrameResult* result, double* t_used) const {
  grpc::ClientContext context;
  prepare(&context, call_timeout);
  v1::GetPvsRequest request;
  request.set_scene_id(scene_id);
  request.set_t(t);
  to_proto(camera, request.mutable_camera());
  v1::GetPvsResponse response;
  const grpc::Status status = stub_->GetPvs(&context, request, &response);
  if (status.ok()) {
    result->pvs.assign(response.pvs().begin(), response.pvs().end());
    result->wake.clear();
    result->stats = from_proto(response.stats());
    if (t_used != nullptr) *t_used = response.t();
  }
  return status;
}

// ---------------------------------------------------------------------------
// Reassembly

namespace {

template <class Ids>
bool strictly_ascending(const Ids& ids) {
  return std::adjacent_find(ids.begin(), ids.end(),
                            [](ObjectId a, ObjectId b) { return a >= b; }) == ids.end();
}

}  // namespace

bool apply_delta(std::vector<ObjectId>* pvs, const std::vector<ObjectId>& removed,
                 const std::vector<ObjectId>& added, std::vector<ObjectId>* scratch,
                 std::string* error, const char* removed_name, const char* added_name) {
  if (!strictly_ascending(removed)) {
    *error = std::string(removed_name) + " ids are not strictly ascending";
    return false;
  }
  if (!strictly_ascending(added)) {
    *error = std::string(added_name) + " ids are not strictly ascending";
    return false;
  }
  // One merge pass: previous minus removed, plus added.
  std::vector<ObjectId>& out = *scratch;
  out.clear();
  out.reserve(pvs->size() + added.size());
  auto r = removed.begin();
  auto a = added.begin();
  for (const ObjectId id : *pvs) {
    while (a != added.end() && *a < id) out.push_back(*a++);
    if (a != added.end() && *a == id) {
      *error = std::string(added_name) + " id " + std::to_string(id) + " is already in the set";
      return false;
    }
    if (r != removed.end() && *r < id) {
      *error = std::string(removed_name) + " id " + std::to_string(*r) + " is not in the set";
      return false;
    }
    if (r != removed.end() && *r == id) {
      ++r;
      continue;
    }
    out.push_back(id);
  }
  if (r != removed.end()) {
    *error = std::string(removed_name) + " id " + std::to_string(*r) + " is not in the set";
    return false;
  }
  out.insert(out.end(), a, added.end());
  pvs->swap(out);
  return true;
}

// ---------------------------------------------------------------------------
// ViewerSession

void ViewerSession::open(const std::string& scene_id, v1::PvsEncoding encoding) {
  start(&v1::Visibility::Stub::View, scene_id, encoding);
  pvs_.clear();
}

bool ViewerSession::frame(std::uint64_t frame_no, double t, const Camera& camera,
                          ViewFrame* out) {
  v1::ViewRequest request;
  if (!ready(&request)) return false;
  request.set_frame(frame_no);
  request.set_t(t);
  to_proto(camera, request.mutable_camera());
  if (!stream_->Write(request)) return false;
  v1::ViewResponse response;
  if (!stream_->Read(&response)) return false;
  if (response.frame() != frame_no) {
    return fail("protocol: asked for frame " + std::to_string(frame_no) + ", got an answer to frame " +
                std::to_string(response.frame()));
  }
  if (response.encoding() != encoding_) {
    return fail(std::string("protocol: asked for ") + v1::PvsEncoding_Name(encoding_) + ", got " +
                v1::PvsEncoding_Name(response.encoding()));
  }
  FrameResult& result = out->result;
  if (encoding_ == v1::PVS_DELTA) {
    const std::vector<ObjectId> removed(response.removed().begin(), response.removed().end());
    const std::vector<ObjectId> added(response.added().begin(), response.added().end());
    std::string why;
    if (!apply_delta(&pvs_, removed, added, &scratch_, &why)) {
      return fail("protocol: frame " + std::to_string(frame_no) + ": PVS delta does not apply: " + why);
    }
    result.pvs = pvs_;
  } else {
    if (!strictly_ascending(response.pvs())) {
      return fail("protocol: frame " + std::to_string(frame_no) + ": pvs is not strictly ascending");
    }
    result.pvs.assign(response.pvs().begin(), response.pvs().end());
  }
  if (!strictly_ascending(response.wake())) {
    return fail("protocol: frame " + std::to_string(frame_no) + ": wake is not strictly ascending");
  }
  result.wake.assign(response.wake().begin(), response.wake().end());
  result.stats = from_proto(response.stats());
  out->frame = response.frame();
  out->t = response.t();
  out->frames_skipped = response.frames_skipped();
  out->server_us = response.server_us();
  return true;
}

// ---------------------------------------------------------------------------
// SimulationSession

SimulationSession::~SimulationSession() {
  if (context_ != nullptr && !finished_) {
    context_->TryCancel();
    if (stream_ != nullptr) stream_->Finish();
  }
}

bool SimulationSession::open(const std::string& scene_id) {
  context_ = std::make_unique<grpc::ClientContext>();
  client_.prepare(context_.get(), std::chrono::milliseconds(0));
  stream_ = client_.stub().Simulate(context_.get());
  finished_ = false;
  wake_ = WakeTracker{};
  protocol_error_.clear();
  v1::SimulateRequest subscribe;
  subscribe.set_scene_id(scene_id);
  return stream_->Write(subscribe);
}

bool SimulationSession::fail(std::string message) {
  protocol_error_ = std::move(message);
  context_->TryCancel();
  return false;
}

bool ids_from_proto(const v1::IdSet& in, std::vector<ObjectId>* out, std::string* error) {
  out->clear();
  if (in.gaps_size() > 0 && (!in.bits().empty() || in.base() != 0)) {
    *error = "holds both gaps and a bitset";
    return false;
  }
  if (!in.bits().empty()) {
    const std::string& bits = in.bits();
    if (std::uint64_t{in.base()} + 8 * std::uint64_t{bits.size()} - 1 > 0xffffffffull) {
      // Only a set bit past the range is an error.
      for (std::size_t k = 0; k < bits.size(); ++k)
        for (int b = 0; b < 8; ++b)
          if ((static_cast<unsigned char>(bits[k]) >> b & 1u) &&
              std::uint64_t{in.base()} + 8 * k + static_cast<std::uint64_t>(b) > 0xffffffffull) {
            *error = "a bit past id 4294967295";
            return false;
          }
    }
    for (std::size_t k = 0; k < bits.size(); ++k) {
      const auto byte = static_cast<unsigned char>(bits[k]);
      for (int b = 0; b < 8; ++b)
        if (byte >> b & 1u) out->push_back(static_cast<ObjectId>(in.base() + 8 * k + static_cast<std::size_t>(b)));
    }
    return true;
  }
  std::uint64_t id = 0;
  out->reserve(static_cast<std::size_t>(in.gaps_size()));
  for (int i = 0; i < in.gaps_size(); ++i) {
    const std::uint32_t gap = in.gaps(i);
    if (i > 0 && gap == 0) {
      *error = "gap " + std::to_string(i) + " is 0: ids are not strictly ascending";
      return false;
    }
    id += gap;
    if (id > 0xffffffffull) {
      *error = "gap " + std::to_string(i) + " leads past id 4294967295";
      return false;
    }
    out->push_back(static_cast<ObjectId>(id));
  }
  return true;
}

bool WakeTracker::apply(const v1::WakeList& wake, std::string* error) {
  const std::string where = "wake list version " + std::to_string(wake.version());
  if (have_ && wake.version() <= version_) {
    *error = where + " does not increase (previous " + std::to_string(version_) + ")";
    return false;
  }
  if (wake.full()) {
    if (!strictly_ascending(wake.ids())) {
      *error = where + ": ids are not strictly ascending";
      return false;
    }
    ids_.assign(wake.ids().begin(), wake.ids().end());
  } else {
    if (!have_) {
      *error = where + ": the first wake list must be full";
      return false;
    }
    const std::vector<ObjectId> slept(wake.slept().begin(), wake.slept().end());
    const std::vector<ObjectId> woken(wake.woken().begin(), wake.woken().end());
    std::string why;
    if (!apply_delta(&ids_, slept, woken, &scratch_, &why, "slept", "woken")) {
      *error = where + ": change does not apply: " + why;
      return false;
    }
  }
  if (wake.size() != ids_.size()) {
    *error = where + ": size " + std::to_string(wake.size()) + " but the list has " + std::to_string(ids_.size()) +
             " ids";
    return false;
  }
  have_ = true;
  version_ = wake.version();
  return true;
}

bool SimulationSession::apply_wake(const v1::WakeList& wake, std::vector<WakeUpdate>* wakes) {
  std::string why;
  if (!wake_.apply(wake, &why)) return fail("protocol: " + why);
  if (wakes != nullptr) wakes->push_back(WakeUpdate{wake.version(), wake.full(), wake_.ids()});
  return true;
}

bool SimulationSession::send(std::uint64_t seq, double t, const std::vector<Move>& moves,
                             MoveAckResult* ack, std::vector<WakeUpdate>* wakes) {
  if (stream_ == nullptr || finished_ || !protocol_error_.empty()) return false;
  v1::SimulateRequest request;
  v1::MoveBatch* batch = request.mutable_batch();
  batch->set_seq(seq);
  batch->set_t(t);
  batch->mutable_moves()->Reserve(static_cast<int>(moves.size()));
  for (const Move& m : moves) to_proto(m, batch->add_moves());
  if (!stream_->Write(request)) return false;
  v1::SimulateResponse response;
  while (stream_->Read(&response)) {
    if (response.has_wake()) {
      if (!apply_wake(response.wake(), wakes)) return false;
      continue;
    }
    if (!response.has_ack()) continue;  // A kind this client does not know.
    const v1::MoveAck& a = response.ack();
    if (a.seq() != seq) {
      return fail("protocol: sent batch " + std::to_string(seq) + ", got the acknowledgement of " +
                  std::to_string(a.seq()));
    }
    ack->seq = a.seq();
    ack->applied = a.applied();
    ack->too_fast.assign(a.too_fast().begin(), a.too_fast().end());
    ack->t = a.t();
    return true;
  }
  return false;
}

grpc::Status SimulationSession::finish(std::vector<WakeUpdate>* wakes) {
  if (stream_ == nullptr) return grpc::Status(grpc::StatusCode::FAILED_PRECONDITION, "not open");
  if (finished_) return grpc::Status(grpc::StatusCode::FAILED_PRECONDITION, "already finished");
  finished_ = true;
  if (protocol_error_.empty()) {
    stream_->WritesDone();
    v1::SimulateResponse response;
    while (stream_->Read(&response)) {
      if (response.has_wake() && !apply_wake(response.wake(), wakes)) break;
    }
  }
  const grpc::Status status = stream_->Finish();
  if (!protocol_error_.empty()) return grpc::Status(grpc::StatusCode::INTERNAL, protocol_error_);
  return status;
}

}  // namespace voxvis::client
