#include "soak.h"

#include "extreme_cameras.h"
#include "meshes.h"
#include "scenes.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <filesystem>
#include <functional>
#include <iterator>
#include <limits>
#include <mutex>
#include <optional>
#include <random>
#include <sstream>
#include <thread>

namespace voxvis::servertest {

const char* const kSoakScene = "soak";

namespace {

using Clock = std::chrono::steady_clock;
using C = grpc::StatusCode;

const std::string kScene = kSoakScene;
const std::string kRace = "race";
const std::string kTickStatic = "tick-static";  // No dynamic object: a PVS depends on its camera alone.
const std::string kTickSmall = "tick-small";    // The wall scene: frames cheap enough for 1,024 viewers.

// The hostile kinds, as reported.
const char* const kBadTime = "GetPvs bad t";
const char* const kBadId = "GetPvs/GetSceneStats bad id";
const char* const kFlood = "GetPvs flood";
const char* const kViewDrop = "View dropped";
const char* const kSimBadMove = "Simulate bad move";
const char* const kSimTooFast = "Simulate too fast";
const char* const kSimHugeStep = "Simulate huge step";
const char* const kRaceCreate = "CreateScene racing";
const char* const kRaceDelete = "DeleteScene racing";
const char* const kRaceFrame = "GetPvs racing";
const char* const kMalformedPvs = "malformed GetPvs";
const char* const kMalformedView = "malformed View";
const char* const kExtremeCamera = "GetPvs extreme camera";
const char* const kCameraBeyond = "GetPvs camera beyond bounds";
const char* const kExtremeView = "View extreme cameras";
const char* const kHugeCreate = "CreateScene huge footprint";
const char* const kMeshCreate = "CreateScene hostile meshes";
const char* const kRebalance = "voxvis rebalance during moves";
const char* const kMoveExport = "ExportScene of a served scene for a move";
const char* const kBurst = "View burst of new streams";
const char* const kTickEntries = "Tick bad entries";
const char* const kTickBadRequest = "Tick bad t or number";
const char* const kTickTooMany = "Tick too many viewers";
const char* const kTickFlood = "Tick flood";
const char* const kTickCancel = "Tick cancelled mid-tick";
const char* const kTickVanish = "Tick left to its deadline";
const char* const kTickBadMove = "Tick bad move";
const char* const kTickWrongRole = "Tick moves with a viewer token";

double ms(Clock::duration d) { return std::chrono::duration<double, std::milli>(d).count(); }

/// Nearest-rank percentiles; zeros for no values.
Spread spread(std::vector<double> v) {
  if (v.empty()) return {};
  std::sort(v.begin(), v.end());
  const auto at = [&](double q) {
    const auto rank = static_cast<std::size_t>(std::ceil(q * static_cast<double>(v.size())));
    return v[std::max<std::size_t>(rank, 1) - 1];
  };
  return {at(0.5), at(0.99), v.back()};
}


/// The good viewer's camera at time t: on an orbit around the scene, looking
/// at its centre.
Camera orbit(double t) {
  const double a = 0.3 * t;
  const Vec3 eye(50 + 90 * std::cos(a), 50 + 30 * std::sin(0.7 * a), 50 + 90 * std::sin(a));
  return look(eye, Vec3(50.0) - eye);
}

/// Outcomes of every kind, shared by the threads.
class Tally {
 public:
  /// Any call may be shed while the server is busy (--max-calls), so
  /// RESOURCE_EXHAUSTED is added to every set; an empty set accepts anything.
  void expect(const std::string& kind, std::set<grpc::StatusCode> codes) {
    if (!codes.empty()) codes.insert(C::RESOURCE_EXHAUSTED);
    std::lock_guard<std::mutex> lock(mu_);
    kinds_[kind].expected = std::move(codes);
  }
  void record(const std::string& kind, const grpc::Status& s, long count = 1) {
    std::lock_guard<std::mutex> lock(mu_);
    HostileKind& k = kinds_[kind];
    k.codes[s.error_code()] += count;
    if (!k.expected.empty() && k.expected.count(s.error_code()) == 0)
      keep_locked(k, code_name(s.error_code()) + ": " + s.error_message().substr(0, 200));
  }
  /// A wrong observation other than a status code.
  void note(const std::string& kind, const std::string& what) {
    std::lock_guard<std::mutex> lock(mu_);
    keep_locked(kinds_[kind], what);
  }
  std::map<std::string, HostileKind> kinds() const {
    std::lock_guard<std::mutex> lock(mu_);
    return kinds_;
  }

 private:
  static void keep_locked(HostileKind& k, const std::string& what) {
    if (k.unexpected.size() < 10) k.unexpected.push_back(what);
  }
  mutable std::mutex mu_;
  std::map<std::string, HostileKind> kinds_;  // Guarded by mu_.
};

/// What every loop of the soak shares.
struct Soak {
  const ServerProcess& server;
  const SoakOptions& options;
  const SceneDesc& scene;
  Tally& tally;
  std::atomic<bool>& stop;
  Clock::time_point start;
  /// The well-behaved tick streams' figures: tick_streams writes them.
  std::vector<TickFigures>& ticks;

  /// Seconds since the start: the times the hostile calls use.
  double now_t() const { return std::chrono::duration<double>(Clock::now() - start).count(); }
  /// A stub on a new connection with the admin's token.
  Api api() const { return server.api(options.admin_token); }

  /// Runs body(round) until stopped, at most as many rounds as the duration
  /// holds pauses, pausing `pause_factor` pauses between rounds.
  void loop(double pause_factor, const std::function<void(int)>& body) const {
    const Seconds pause = options.pause * pause_factor;
    const int max_rounds = 1 + static_cast<int>(options.duration / pause);
    for (int round = 0; round < max_rounds && !stop.load(); ++round) {
      body(round);
      std::this_thread::sleep_for(pause);
    }
  }
};

// --- The good viewer ------------------------------------------------------

ViewerFigures run_viewer(const Soak& s) {
  const Api api = s.api();
  ViewStream stream(api, kScene, v1::PVS_FULL, s.options.duration + Seconds(120));
  ViewerFigures f;
  std::mutex mu;
  std::map<std::uint64_t, Clock::time_point> sent_at;  // Guarded by mu.
  std::vector<double> gaps, rtts, engine;              // Guarded by mu.
  std::thread reader([&] {
    v1::ViewResponse r;
    std::optional<Clock::time_point> previous;
    while (stream.read(&r)) {
      const Clock::time_point now = Clock::now();
      std::lock_guard<std::mutex> lock(mu);
      if (f.answered > 0 && r.frame() <= f.last_answered) f.increasing = false;
      ++f.answered;
      f.skipped += r.frames_skipped();
      f.last_answered = r.frame();
      engine.push_back(r.stats().time_us() / 1000.0);
      if (previous) gaps.push_back(ms(now - *previous));
      previous = now;
      const auto it = sent_at.find(r.frame());
      if (it != sent_at.end()) {
        rtts.push_back(ms(now - it->second));
        sent_at.erase(sent_at.begin(), std::next(it));
      }
    }
  });
  const double hz = s.options.viewer_hz;
  const auto period = std::chrono::duration_cast<Clock::duration>(Seconds(1.0 / hz));
  Clock::time_point next = Clock::now();
  for (std::uint64_t frame = 1; !s.stop.load(); ++frame) {
    std::this_thread::sleep_until(next);
    next += period;
    const double t = static_cast<double>(frame) / hz;
    {
      std::lock_guard<std::mutex> lock(mu);
      sent_at[frame] = Clock::now();
    }
    const bool written = stream.send(frame, t, orbit(t));
    std::lock_guard<std::mutex> lock(mu);
    if (!written) {
      f.errors.push_back("the write of frame " + std::to_string(frame) + " failed");
      break;
    }
    f.sent = f.last_sent = frame;
  }
  stream.writes_done();
  reader.join();
  const grpc::Status status = stream.finish();
  if (!status.ok())
    f.errors.push_back("the stream ended " + code_name(status.error_code()) + ": " +
                       status.error_message());
  f.gaps = spread(std::move(gaps));
  f.round_trip = spread(std::move(rtts));
  f.engine = spread(std::move(engine));
  return f;
}

// --- The hostile mix --------------------------------------------------------

void bad_times(const Soak& s) {
  s.tally.expect(kBadTime, {C::INVALID_ARGUMENT});
  const Api api = s.api();
  const double bad[] = {1e308, -1e308, std::numeric_limits<double>::quiet_NaN(), 1.7e15,
                        std::numeric_limits<double>::infinity()};
  s.loop(1, [&](int) {
    v1::GetPvsResponse r;
    for (double t : bad) s.tally.record(kBadTime, api.get_pvs(kScene, t, orbit(0), &r));
  });
}

void bad_ids(const Soak& s) {
  s.tally.expect(kBadId, {C::INVALID_ARGUMENT});
  const Api api = s.api();
  const std::string bad[] = {std::string(8000, 'q'), "", "../x"};
  s.loop(1, [&](int) {
    v1::GetPvsResponse r;
    v1::SceneInfo info;
    for (const std::string& id : bad) {
      s.tally.record(kBadId, api.get_pvs(id, s.now_t(), orbit(0), &r));
      s.tally.record(kBadId, api.stats(id, &info));
    }
  });
}

// A few hundred GetPvs at once on a connection of their own, with short
// deadlines; every third flood is cancelled 20 ms after it is sent.
void floods(const Soak& s) {
  s.tally.expect(kFlood, {C::OK, C::DEADLINE_EXCEEDED, C::CANCELLED});
  s.loop(10, [&](int round) {
    const Api api = s.api();
    const Seconds deadline = round % 2 == 0 ? Seconds(0.5) : Seconds(0.05);
    PvsFlood flood(api, kScene, s.options.flood_calls, s.now_t(), orbit(s.now_t()), deadline);
    if (round % 3 == 2) {
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
      flood.cancel();
    }
    if (!flood.wait_all(Seconds(60)))
      s.tally.note(kFlood, "calls of a flood still open 60 s after it was sent");
    for (int c = 0; c <= static_cast<int>(grpc::StatusCode::UNAUTHENTICATED); ++c) {
      const auto code = static_cast<grpc::StatusCode>(c);
      if (const int n = flood.with_code(code); n > 0)
        s.tally.record(kFlood, grpc::Status(code, "a call of a flood"), n);
    }
  });
}

// View streams on connections of their own that send frames and never read
// their answers: cancelled at once, cancelled after one answer, or left to a
// short deadline. Each connection closes with its round.
void view_drops(const Soak& s) {
  s.tally.expect(kViewDrop, {C::CANCELLED, C::DEADLINE_EXCEEDED});
  s.loop(1, [&](int round) {
    const Api api = s.api();
    const int how = round % 3;
    ViewStream v(api, kScene, v1::PVS_FULL, how == 2 ? Seconds(0.3) : Seconds(30));
    const double t0 = s.now_t();
    for (int f = 1; f <= 5; ++f)
      if (!v.send(static_cast<std::uint64_t>(f), t0 + 0.01 * f, orbit(t0))) break;
    v1::ViewResponse r;
    if (how == 1) v.read(&r);
    if (how == 2) {
      std::this_thread::sleep_for(std::chrono::milliseconds(400));
    } else {
      v.context().TryCancel();
    }
    s.tally.record(kViewDrop, v.finish());
  });
}

// Simulate streams on the good viewer's scene, in turn: a bad move (unknown
// id, static id, NaN centre, centre beyond 1e12), moves far too fast (50
// units in 10 ms, or out to 1e11 and back), and a batch 10^6 s ahead.
void simulations(const Soak& s) {
  s.tally.expect(kSimBadMove, {C::INVALID_ARGUMENT});
  s.tally.expect(kSimTooFast, {C::OK});
  s.tally.expect(kSimHugeStep, {C::INVALID_ARGUMENT});
  const std::vector<ObjectDesc>& objects = s.scene.objects;
  const auto moving = [](const ObjectDesc& o) { return o.dynamic; };
  const auto dynamic = std::find_if(objects.begin(), objects.end(), moving);
  const auto fixed = std::find_if_not(objects.begin(), objects.end(), moving);
  if (dynamic == objects.end() || fixed == objects.end())
    return s.tally.note(kSimBadMove, "the scene needs a dynamic and a static object");
  const ObjectId id = dynamic->id;
  const Vec3 home = dynamic->center;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const std::vector<Move> bad_moves = {
      {999999, home}, {fixed->id, home}, {id, Vec3(nan, 1, 1)}, {id, Vec3(1e13, 50, 50)}};
  s.loop(2, [&](int round) {
    const Api api = s.api();
    SimStream sim(api, kScene, Seconds(30));
    const double t = s.now_t();
    v1::MoveAck ack;
    const char* kind = kSimBadMove;
    std::vector<std::string> wrong;  // Kept unless the stream was shed.
    if (round % 3 == 0) {
      sim.send(1, t, {bad_moves[static_cast<std::size_t>(round / 3) % bad_moves.size()]});
      if (sim.wait_ack(&ack, Seconds(10))) wrong.push_back("a bad move was acknowledged");
    } else if (round % 3 == 1) {
      kind = kSimTooFast;
      const Vec3 away = round % 2 == 0 ? home + Vec3(50, 0, 0) : Vec3(1e11, 50, 50);
      if (!sim.move(1, t, {{id, home}}, &ack) || !sim.move(2, t + 0.01, {{id, away}}, &ack)) {
        wrong.push_back("a batch of moves was not acknowledged");
      } else {
        if (std::count(ack.too_fast().begin(), ack.too_fast().end(), id) == 0)
          wrong.push_back("a move far too fast was not flagged");
        if (!sim.move(3, t + 0.02, {{id, home}}, &ack))
          wrong.push_back("the move back was not acknowledged");
      }
    } else {
      kind = kSimHugeStep;
      if (!sim.move(1, t, {}, &ack)) wrong.push_back("an empty batch was not acknowledged");
      sim.send(2, t + 1e6, {});
      if (sim.wait_ack(&ack, Seconds(10))) wrong.push_back("a step of 1e6 s was acknowledged");
    }
    for (const std::string& e : sim.protocol_errors()) wrong.push_back(e);
    const grpc::Status status = sim.finish();
    s.tally.record(kind, status);
    if (status.error_code() != C::RESOURCE_EXHAUSTED)
      for (const std::string& w : wrong) s.tally.note(kind, w);
  });
}

// DeleteScene and CreateScene of one id from two threads (on two
// connections), while a third asks for a frame of it.
void races(const Soak& s) {
  s.tally.expect(kRaceCreate, {C::OK, C::ABORTED, C::ALREADY_EXISTS});
  s.tally.expect(kRaceDelete, {C::OK});
  s.tally.expect(kRaceFrame, {C::OK, C::NOT_FOUND});
  const Api api = s.api();
  const Api other = s.api();
  const std::string file = s.server.data_dir() + "/scenes/" + kRace + ".json";
  // Observations retried while the server sheds calls, for at most 5 s.
  const auto retried = [](const std::function<grpc::Status()>& call) {
    grpc::Status st = call();
    for (int i = 0; i < 250 && st.error_code() == C::RESOURCE_EXHAUSTED; ++i) {
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
      st = call();
    }
    return st;
  };
  s.loop(1, [&](int round) {
    v1::SceneInfo info;
    grpc::Status st = retried([&] { return api.stats(kRace, &info); });
    if (st.error_code() == C::NOT_FOUND)
      st = retried([&] { return api.create_scene_json(kRace, wall_scene_json()); });
    if (!st.ok()) {
      if (st.error_code() != C::RESOURCE_EXHAUSTED)
        s.tally.note(kRaceCreate, "round " + std::to_string(round) + ": before it, " +
                                      code_name(st.error_code()) + ": " + st.error_message());
      return;
    }
    grpc::Status deleted, created, frame;
    std::thread del([&] { deleted = other.delete_scene(kRace); });
    std::thread viewer([&] {
      v1::GetPvsResponse r;
      frame = s.api().get_pvs(kRace, 0.0, wall_camera(), &r);
    });
    std::this_thread::sleep_for(std::chrono::microseconds(500 * (round % 5)));
    created = api.create_scene_json(kRace, wall_scene_json());
    del.join();
    viewer.join();
    s.tally.record(kRaceDelete, deleted);
    s.tally.record(kRaceCreate, created);
    s.tally.record(kRaceFrame, frame);
    const grpc::Status stats = retried([&] { return api.stats(kRace, &info); });
    std::vector<std::string> ids;
    const grpc::Status list = retried([&] { return api.list_scenes(&ids); });
    if (stats.error_code() == C::RESOURCE_EXHAUSTED || list.error_code() == C::RESOURCE_EXHAUSTED)
      return;  // Still busy after 5 s: the round is not observed.
    const bool served = stats.ok();
    const bool listed = std::find(ids.begin(), ids.end(), kRace) != ids.end();
    const bool stored = std::filesystem::exists(file);
    // A delete that ran leaves the scene exactly when the create was
    // acknowledged; one shed leaves it as it was (present).
    const bool expected = !deleted.ok() || created.ok();
    if (!list.ok() || served != listed || served != stored || served != expected) {
      std::ostringstream o;
      o << "round " << round << ": delete " << code_name(deleted.error_code()) << ", create "
        << code_name(created.error_code()) << "; then served " << served << ", listed " << listed
        << ", file " << stored << " (GetSceneStats " << code_name(stats.error_code())
        << ", ListScenes " << code_name(list.error_code()) << ")";
      s.tally.note(kRaceCreate, o.str());
    }
  });
}

// Bytes that are not the request message, to GetPvs and View by name.
void malformed(const Soak& s) {
  s.tally.expect(kMalformedPvs, {});  // Any outcome but a crash.
  s.tally.expect(kMalformedView, {});
  const std::shared_ptr<grpc::Channel> channel = s.server.channel();
  const std::vector<std::string> fixed = {
      std::string("\xff\xff\xff\xff\xff", 5),      // a tag that does not end
      std::string("\x0a\xff\xff\xff\xff\x0f", 6),  // scene_id longer than the message
      std::string("\x0a\x05so", 4),                // scene_id cut short
      std::string("\x11\x00\x00", 3),              // field 2 as fixed64, cut short
      std::string("\x1a\x03\x0a\x01", 4),          // camera.eye cut short
      std::string("\x0a\x04soak\x12\x01x", 9),     // t with the wrong wire type
      std::string(),                               // the empty message
  };
  std::mt19937_64 rng(s.options.seed);
  s.loop(2, [&](int round) {
    std::string bytes;
    if (round % 2 == 0) {
      bytes = fixed[static_cast<std::size_t>(round / 2) % fixed.size()];
    } else {
      bytes.resize(1 + rng() % 64);
      for (char& c : bytes) c = static_cast<char>(rng());
    }
    std::string response;
    std::vector<std::string> responses;
    s.tally.record(kMalformedPvs, generic_unary(channel, "/voxvis.v1.Visibility/GetPvs", bytes,
                                                &response, Seconds(5), s.options.admin_token));
    s.tally.record(kMalformedView, generic_bidi(channel, "/voxvis.v1.Visibility/View", bytes,
                                                &responses, Seconds(5), s.options.admin_token));
  });
}

// Cameras at the documented bounds and beyond them, by GetPvs and on View
// streams: the accepted ones are answered, the others refused naming the
// field; none may take the server down.
void cameras(const Soak& s) {
  s.tally.expect(kExtremeCamera, {C::OK});
  s.tally.expect(kCameraBeyond, {C::INVALID_ARGUMENT});
  s.tally.expect(kExtremeView, {C::OK});
  const Api api = s.api();
  Rng rng(s.options.seed ^ 0xca3e);
  const double beyond_fov[] = {test::kDenormal, 1e-322, 1e-300, 0.0, 180.0};
  s.loop(2, [&](int round) {
    v1::GetPvsResponse r;
    s.tally.record(kExtremeCamera, api.get_pvs(kScene, s.now_t(), test::extreme_camera(rng, s.scene), &r));
    Camera bad = orbit(s.now_t());
    bad.fov_y_deg = beyond_fov[static_cast<std::size_t>(round) % std::size(beyond_fov)];
    const grpc::Status refused = api.get_pvs(kScene, s.now_t(), bad, &r);
    s.tally.record(kCameraBeyond, refused);
    if (!refused.ok() && refused.error_message().find("camera.fov_y_deg") == std::string::npos)
      s.tally.note(kCameraBeyond, "the refusal does not name camera.fov_y_deg: " + refused.error_message());
    if (round % 10 != 0) return;
    ViewStream v(api, kScene, v1::PVS_DELTA, Seconds(30));
    const double t0 = s.now_t();
    for (std::uint64_t f = 1; f <= 5; ++f) {
      v1::ViewResponse vr;
      if (!v.frame(f, t0 + 0.001 * static_cast<double>(f), test::extreme_camera(rng, s.scene), &vr)) break;
    }
    s.tally.record(kExtremeView, v.finish());
  });
}

// Creates whose objects cover the grid many times over: refused by the
// footprint estimate (over the soak server's --memory-budget-mib), or, with
// a short deadline, stopped when it passes. Never registered, never built
// on a frame worker.
void huge_creates(const Soak& s) {
  s.tally.expect(kHugeCreate, {C::RESOURCE_EXHAUSTED, C::DEADLINE_EXCEEDED, C::CANCELLED});
  v1::SceneDescription huge;
  to_proto(huge_footprint_scene(100000), &huge);
  s.loop(40, [&](int round) {
    const Api admin = s.api();
    grpc::ClientContext ctx;
    admin.prepare(&ctx, round % 2 ? Seconds(0.3) : Seconds(30));
    v1::CreateSceneRequest req;
    req.set_scene_id("huge");
    *req.mutable_description() = huge;
    v1::SceneInfo info;
    s.tally.record(kHugeCreate, admin.stub().CreateScene(&ctx, req, &info));
  });
}

/// test::copied_triangle_scene on the wire.
v1::SceneDescription copied_triangles(int copies, double leg) {
  v1::SceneDescription wire;
  to_proto(test::copied_triangle_scene(copies, leg), &wire);
  return wire;
}

// Mesh creates that once escaped the budget or held the build thread: many
// copies of a large triangle (built within the budget, then deleted), of a
// small one, and a mesh placed so often that its saved file is too large
// (refused at once); every other one with a deadline of 0.3 s.
void mesh_creates(const Soak& s) {
  s.tally.expect(kMeshCreate, {C::OK, C::RESOURCE_EXHAUSTED, C::DEADLINE_EXCEEDED, C::CANCELLED});
  // 5,000 triangles on three vertices, placed 20,000 times: a small
  // message whose saved file would be about 1.5 GB.
  v1::SceneDescription instanced = copied_triangles(1, 1.0);
  for (int k = 1; k < 5000; ++k)
    for (std::uint32_t v : {0u, 1u, 2u}) instanced.mutable_meshes(0)->add_triangles(v);
  for (int i = 1; i < 20000; ++i) {
    v1::Object* o = instanced.add_objects();
    *o = instanced.objects(0);
    o->set_id(static_cast<std::uint32_t>(i + 1));
  }
  // Under AddressSanitizer a build runs several times slower, and two builds
  // of 20,000 triangles would hold both of the server's workers past the
  // racing creates' 30 s deadline (seen on a busy 2-core machine): a tenth
  // of the triangles there keeps the same pattern.
#if defined(__SANITIZE_ADDRESS__)
  constexpr int kScale = 10;
#else
  constexpr int kScale = 1;
#endif
  const v1::SceneDescription cases[] = {copied_triangles(400 / kScale, 90.0), copied_triangles(20000 / kScale, 1.0),
                                        instanced};
  s.loop(40, [&](int round) {
    const Api admin = s.api();
    const std::string id = "mesh-" + std::to_string(round);
    grpc::ClientContext ctx;
    admin.prepare(&ctx, round % 2 ? Seconds(0.3) : Seconds(60));
    v1::CreateSceneRequest req;
    req.set_scene_id(id);
    *req.mutable_description() = cases[static_cast<std::size_t>(round) % std::size(cases)];
    v1::SceneInfo info;
    const grpc::Status st = admin.stub().CreateScene(&ctx, req, &info);
    s.tally.record(kMeshCreate, st);
    if (st.ok() && !admin.delete_scene(id).ok()) s.tally.note(kMeshCreate, "a mesh scene created could not be deleted");
  });
}

// voxvis rebalance beside the simulation's moves: a second server, shard b
// of [a, b], against the soak's (no --shard: it serves every scene as its
// own). Every scene b owns is reported and left where it is (exit 2), never
// moved while it is served; the server enforces it on a move's export and
// delete of the viewer's scene too (FAILED_PRECONDITION).
void rebalances(const Soak& s) {
  s.tally.expect(kRebalance, {C::OK, C::FAILED_PRECONDITION});
  s.tally.expect(kMoveExport, {C::FAILED_PRECONDITION});
  ServerProcess target({"--shard", "b", "--fleet", "a,b"});
  if (!target.start()) {
    s.tally.note(kRebalance, "the second server did not start");
    return;
  }
  const std::string servers = "a=" + s.server.address() + ",b=" + target.address();
  const std::string token_file = target.path("admin-token");
  spit(token_file, s.options.admin_token + "\n");
  s.loop(20, [&](int) {
    const ProcessResult r = run_program({VOXVIS_CLI, "rebalance", "--servers", servers, "--token-file", token_file},
                                        target.dir(), Seconds(60));
    s.tally.record(kRebalance, r.status == 0   ? grpc::Status::OK
                               : r.status == 2 ? grpc::Status(grpc::StatusCode::FAILED_PRECONDITION, r.err)
                                               : grpc::Status(grpc::StatusCode::UNKNOWN, r.err));
    if (r.status == 2 && r.err.find("left there") == std::string::npos)
      s.tally.note(kRebalance, "exit 2 without a scene left: " + r.err);
    std::vector<std::string> on_b;
    if (target.api().list_scenes(&on_b).ok() && !on_b.empty())
      s.tally.note(kRebalance, "a scene the soak server serves was moved to " + on_b.front());
    const Api admin = s.api();
    grpc::ClientContext ctx;
    admin.prepare(&ctx, Seconds(10));
    v1::ExportSceneRequest req;
    req.set_scene_id(kScene);
    req.set_only_if_misplaced(true);
    v1::ExportSceneResponse out;
    s.tally.record(kMoveExport, admin.stub().ExportScene(&ctx, req, &out));
  });
}

// A hundred new View streams at once over two new connections, each
// sending one frame: every one answered.
void stream_bursts(const Soak& s) {
  s.tally.expect(kBurst, {C::OK});
  s.loop(100, [&](int) {
    const Api a = s.api(), b = s.api();
    std::vector<std::unique_ptr<ViewStream>> streams;
    const double t = s.now_t();
    for (int i = 0; i < 100; ++i) {
      streams.push_back(std::make_unique<ViewStream>(i % 2 ? a : b, kScene, v1::PVS_FULL, Seconds(60)));
      streams.back()->send(1, t, orbit(t + 0.01 * i));
    }
    for (auto& v : streams) {
      v1::ViewResponse r;
      if (!v->read(&r)) s.tally.note(kBurst, "a new stream's first frame was not answered");
      s.tally.record(kBurst, v->finish());
    }
  });
}

// --- Tick streams -------------------------------------------------------------

/// A viewer of a tick request: its id and camera.
using TickCam = std::pair<std::uint64_t, Camera>;

v1::TickRequest tick_request(const std::string& scene, v1::PvsEncoding encoding, std::uint64_t tick, double t,
                             const std::vector<TickCam>& viewers, const std::vector<Move>& moves = {},
                             const std::vector<std::uint64_t>& left = {}) {
  v1::TickRequest r;
  r.set_scene_id(scene);  // Every request names it: allowed when it matches.
  r.set_encoding(encoding);
  r.set_tick(tick);
  r.set_t(t);
  for (const Move& m : moves) {
    v1::Move* mv = r.add_moves();
    mv->set_id(m.id);
    to_proto(m.center, mv->mutable_center());
  }
  for (const auto& [id, camera] : viewers) {
    v1::TickViewer* v = r.add_viewers();
    v->set_viewer(id);
    to_proto(camera, v->mutable_camera());
  }
  for (std::uint64_t id : left) r.add_left(id);
  return r;
}

/// One Tick stream on the generated stub (sync API), on the connection of
/// `api`, with a deadline `timeout` from now.
class TickCall {
 public:
  TickCall(const Api& api, Seconds timeout) {
    api.prepare(&ctx_, timeout);
    stream_ = api.stub().Tick(&ctx_);
  }
  bool send(const v1::TickRequest& r) { return stream_->Write(r); }
  bool read(v1::TickResponse* r) { return stream_->Read(r); }
  bool writes_done() { return stream_->WritesDone(); }
  void cancel() { ctx_.TryCancel(); }
  /// Half-closes, reads what is left (counted in `*drained`) and returns the
  /// call's status.
  grpc::Status finish(std::size_t* drained = nullptr) {
    stream_->WritesDone();
    v1::TickResponse r;
    while (stream_->Read(&r))
      if (drained) ++*drained;
    return stream_->Finish();
  }
  /// The status after the reads have ended.
  grpc::Status status() { return stream_->Finish(); }

 private:
  grpc::ClientContext ctx_;
  std::unique_ptr<grpc::ClientReaderWriter<v1::TickRequest, v1::TickResponse>> stream_;
};

std::string ids_text(const std::vector<ObjectId>& ids) {
  std::string out = "[";
  for (std::size_t i = 0; i < ids.size() && i < 8; ++i) {
    if (i > 0) out += ',';
    out += std::to_string(ids[i]);
  }
  out += ids.size() > 8 ? ",...]" : "]";
  return out;
}

/// `count` dynamic objects of `scene` at their homes, ascending ids: the
/// last ones (`from_end`) or those from the middle on. The loops that move
/// objects take disjoint ones (simulations the first).
std::vector<Move> dynamic_homes(const SceneDesc& scene, std::size_t count, bool from_end) {
  std::vector<Move> all;
  for (const ObjectDesc& o : scene.objects)
    if (o.dynamic) all.push_back({o.id, o.center});
  std::sort(all.begin(), all.end(), [](const Move& a, const Move& b) { return a.id < b.id; });
  const std::size_t from = from_end ? all.size() - std::min(count, all.size()) : all.size() / 2;
  return {all.begin() + static_cast<std::ptrdiff_t>(from),
          all.begin() + static_cast<std::ptrdiff_t>(std::min(all.size(), from + count))};
}

/// Where an object of a tick stream is at time t: on a circle of radius 1
/// around its home, at 1 unit a second (the lattice's max_speed is 5).
Vec3 circling(const Move& home, double t) {
  const double a = t + 0.7 * home.id;
  return home.center + Vec3(std::cos(a), 0.0, std::sin(a));
}

/// A well-behaved Tick stream: what it sends and how it checks the answers.
struct GoodTicks {
  std::string name;
  std::string scene;
  std::string token;
  v1::PvsEncoding encoding = v1::PVS_DELTA;
  /// Viewers 1..viewers; the last one leaves for 10 ticks in every 40 (named
  /// in `left`) and comes back as a new viewer.
  int viewers = 3;
  std::vector<Move> homes;  ///< Objects of its own, moved every tick.
  std::function<Camera(int viewer, std::uint64_t tick, double t)> camera;
  /// Compares a viewer's PVS with GetPvs's every 10th answer (static scenes).
  bool check_with_get_pvs = false;
};

TickFigures run_good_ticks(const Soak& s, const GoodTicks& g) {
  TickFigures f;
  f.name = g.name;
  const Api api = s.server.api(g.token);
  const Api checker = s.api();
  TickCall call(api, s.options.duration + Seconds(120));
  struct Sent {
    double t = 0.0;
    std::vector<TickCam> viewers;
    std::vector<std::uint64_t> left;
  };
  // The sender writes sent, sent/last_sent and moves_sent of `f`; the reader
  // the rest; `errors` both.
  std::mutex mu;
  std::map<std::uint64_t, Sent> sent;  // Guarded by mu: ticks not answered yet.
  const auto error = [&](const std::string& e) {
    std::lock_guard<std::mutex> lock(mu);
    if (f.errors.size() < 10) f.errors.push_back(e);
  };
  std::vector<double> gaps;  // The reader's.
  std::thread reader([&] {
    v1::TickResponse r;
    std::optional<Clock::time_point> previous;
    std::map<std::uint64_t, std::vector<ObjectId>> base;  // Each viewer's PVS as last answered.
    client::WakeTracker wake;
    std::vector<ObjectId> pvs, added, removed, ids;
    while (call.read(&r)) {
      const Clock::time_point now = Clock::now();
      if (previous) gaps.push_back(ms(now - *previous));
      previous = now;
      const std::string at = "tick " + std::to_string(r.tick()) + ": ";
      if (f.answered > 0 && r.tick() <= f.last_answered) error(at + "answered after " + std::to_string(f.last_answered));
      ++f.answered;
      f.last_answered = r.tick();
      f.skipped += r.ticks_skipped();
      f.moves_applied += r.moves_applied();
      std::string why;
      if (r.has_wake() && !wake.apply(r.wake(), &why)) error(at + "wake list: " + why);
      if (r.encoding() != g.encoding) error(at + "encoding " + std::to_string(r.encoding()));
      std::optional<Sent> found;
      {
        std::lock_guard<std::mutex> lock(mu);
        const auto it = sent.find(r.tick());
        if (it != sent.end()) {
          // The viewers named in `left` up to this tick, answered or
          // replaced, are gone before its frames: a viewer back since is new.
          for (auto k = sent.begin(); k != std::next(it); ++k)
            for (std::uint64_t id : k->second.left) base.erase(id);
          found = std::move(it->second);
          sent.erase(sent.begin(), std::next(it));
        }
      }
      if (!found) {
        error(at + "never sent, or answered twice");
        continue;
      }
      const Sent& tick = *found;
      if (r.answers_size() != static_cast<int>(tick.viewers.size())) {
        error(at + std::to_string(r.answers_size()) + " answers to " + std::to_string(tick.viewers.size()) + " viewers");
        continue;
      }
      for (int i = 0; i < r.answers_size(); ++i) {
        const v1::TickAnswer& a = r.answers(i);
        const auto& [id, camera] = tick.viewers[static_cast<std::size_t>(i)];
        const std::string who = at + "viewer " + std::to_string(id) + ": ";
        if (a.viewer() != id) error(who + "answered as viewer " + std::to_string(a.viewer()));
        if (a.has_error()) {
          error(who + "refused: " + a.error().field() + ": " + a.error().description());
          continue;
        }
        ++f.viewer_answers;
        if (!client::ids_from_proto(a.wake(), &ids, &why)) error(who + "wake: " + why);
        if (g.encoding == v1::PVS_FULL) {
          if (!client::ids_from_proto(a.pvs(), &pvs, &why)) error(who + "pvs: " + why);
        } else {
          if (!client::ids_from_proto(a.added(), &added, &why) || !client::ids_from_proto(a.removed(), &removed, &why))
            error(who + "delta: " + why);
          if (a.has_pvs() && (a.pvs().gaps_size() > 0 || !a.pvs().bits().empty())) error(who + "a full PVS in a delta");
          const std::vector<ObjectId>& was = base[id];
          ids.clear();
          std::set_intersection(added.begin(), added.end(), was.begin(), was.end(), std::back_inserter(ids));
          if (!ids.empty()) error(who + "adds ids it had: " + ids_text(ids));
          ids.clear();
          std::set_difference(removed.begin(), removed.end(), was.begin(), was.end(), std::back_inserter(ids));
          if (!ids.empty()) error(who + "removes ids it did not have: " + ids_text(ids));
          ids.clear();
          std::set_difference(was.begin(), was.end(), removed.begin(), removed.end(), std::back_inserter(ids));
          pvs.clear();
          std::set_union(ids.begin(), ids.end(), added.begin(), added.end(), std::back_inserter(pvs));
        }
        if (pvs.size() != a.stats().pvs_size())
          error(who + "a PVS of " + std::to_string(pvs.size()) + " ids, stats.pvs_size " +
                std::to_string(a.stats().pvs_size()));
        base[id] = pvs;
        if (g.check_with_get_pvs && f.viewer_answers % 10 == 1) {
          v1::GetPvsResponse full;
          const grpc::Status st = checker.get_pvs(g.scene, tick.t, camera, &full);
          if (st.ok()) {
            ++f.pvs_checked;
            const std::vector<ObjectId> expected = ids_of(full.pvs());
            if (expected != pvs)
              error(who + "PVS " + ids_text(pvs) + " of " + std::to_string(pvs.size()) + " ids, GetPvs " +
                    ids_text(expected) + " of " + std::to_string(expected.size()));
          } else if (st.error_code() != C::RESOURCE_EXHAUSTED) {
            error(who + "GetPvs for the check: " + code_name(st.error_code()) + " " + st.error_message());
          }
        }
      }
    }
  });
  const auto period = std::chrono::duration_cast<Clock::duration>(Seconds(1.0 / s.options.tick_hz));
  Clock::time_point next = Clock::now();
  std::map<ObjectId, Vec3> centres;
  const auto present = [](int v, int last, std::uint64_t tick) { return v != last || (tick / 10) % 4 != 3; };
  for (std::uint64_t tick = 1; !s.stop.load(); ++tick) {
    std::this_thread::sleep_until(next);
    next += period;
    const double t = s.now_t();
    Sent out;
    out.t = t;
    for (int v = 1; v <= g.viewers; ++v) {
      if (present(v, g.viewers, tick)) {
        out.viewers.emplace_back(static_cast<std::uint64_t>(v), g.camera(v, tick, t));
      } else if (present(v, g.viewers, tick - 1)) {
        out.left.push_back(static_cast<std::uint64_t>(v));
      }
    }
    std::vector<Move> moves;
    for (const Move& home : g.homes) moves.push_back({home.id, circling(home, t)});
    const v1::TickRequest request = tick_request(g.scene, g.encoding, tick, t, out.viewers, moves, out.left);
    {
      std::lock_guard<std::mutex> lock(mu);
      sent[tick] = std::move(out);
    }
    if (!call.send(request)) {
      error("the write of tick " + std::to_string(tick) + " failed");
      break;
    }
    f.sent = f.last_sent = tick;
    f.moves_sent += moves.size();
    for (const Move& m : moves) centres[m.id] = m.center;
  }
  call.writes_done();
  reader.join();
  const grpc::Status status = call.status();
  if (!status.ok()) error("the stream ended " + code_name(status.error_code()) + ": " + status.error_message());
  for (const auto& [id, centre] : centres) f.final_centres.push_back({id, centre});
  f.gaps = spread(std::move(gaps));
  return f;
}

/// The viewer `v`'s camera on the viewer's scene: viewers 1 and 2 orbit it
/// (2 half a turn behind), the others look around from its middle.
Camera soak_tick_camera(int v, std::uint64_t, double t) {
  if (v == 1) return orbit(t);
  if (v == 2) return orbit(t + 10.5);
  return look(Vec3(50.0 + v, 50.0, 50.0), Vec3(std::cos(0.5 * t), 0.2, std::sin(0.5 * t)));
}

/// The hostile tick streams, each its own kind, in turn: a round of each
/// opens a stream of its own on a connection of its own.
void hostile_ticks(const Soak& s) {
  s.tally.expect(kTickEntries, {C::OK});
  s.tally.expect(kTickBadRequest, {C::INVALID_ARGUMENT});
  s.tally.expect(kTickTooMany, {C::INVALID_ARGUMENT});
  s.tally.expect(kTickFlood, {C::OK});
  s.tally.expect(kTickCancel, {C::CANCELLED});
  s.tally.expect(kTickVanish, {C::DEADLINE_EXCEEDED, C::CANCELLED});
  s.tally.expect(kTickBadMove, {C::INVALID_ARGUMENT});
  s.tally.expect(kTickWrongRole, {C::PERMISSION_DENIED});
  const std::vector<ObjectDesc>& objects = s.scene.objects;
  const auto fixed = std::find_if_not(objects.begin(), objects.end(), [](const ObjectDesc& o) { return o.dynamic; });
  const std::vector<Move> movers = dynamic_homes(s.scene, 6, false);
  if (fixed == objects.end() || movers.size() < 6)
    return s.tally.note(kTickBadMove, "the scene needs static objects and 6 dynamic ones");
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const auto moved = [&](double t) {
    std::vector<Move> m;
    for (const Move& home : movers) m.push_back({home.id, circling(home, t)});
    return m;
  };
  const auto cams = [](double t, int n, std::uint64_t first = 1) {
    std::vector<TickCam> v;
    for (int i = 0; i < n; ++i) v.emplace_back(first + static_cast<std::uint64_t>(i), orbit(t + 2.0 * i));
    return v;
  };
  // A round's observations, kept unless its stream was shed as busy.
  std::vector<std::string> wrong;
  const auto record = [&](const char* kind, const grpc::Status& status) {
    s.tally.record(kind, status);
    if (status.error_code() != C::RESOURCE_EXHAUSTED)
      for (const std::string& w : wrong) s.tally.note(kind, w);
    wrong.clear();
  };
  // The refusal names `field` (its text starts "field: ").
  const auto names = [&](const grpc::Status& st, const std::string& field) {
    if (st.error_code() == C::INVALID_ARGUMENT && st.error_message().rfind(field + ": ", 0) != 0)
      wrong.push_back("refused without naming " + field + ": " + st.error_message());
  };
  s.loop(2, [&](int round) {
    const Api api = s.api();
    const double t = s.now_t();
    v1::TickResponse r;
    switch (round % 8) {
      case 0: {
        // Bad cameras and a viewer id given twice, among good entries: those
        // entries refused naming their field, the others answered.
        TickCall call(api, Seconds(30));
        for (std::uint64_t tick = 1; tick <= 3; ++tick) {
          std::vector<TickCam> v = cams(t, 6);
          v[1].second.fov_y_deg = 190.0;
          v[2].first = v[0].first;
          v[3].second.eye.x = nan;
          v[4].second.dir = Vec3(0.0);
          const std::vector<std::string> fields = {"", "viewers[1].camera.fov_y_deg", "viewers[2].viewer",
                                                   "viewers[3].camera.eye", "viewers[4].camera.dir", ""};
          if (!call.send(tick_request(kScene, v1::PVS_DELTA, tick, t + 0.01 * static_cast<double>(tick), v)) || !call.read(&r)) {
            wrong.push_back("tick " + std::to_string(tick) + " was not answered");
            break;
          }
          for (int i = 0; i < r.answers_size() && i < 6; ++i) {
            if (r.answers(i).error().field() != fields[static_cast<std::size_t>(i)])
              wrong.push_back("entry " + std::to_string(i) + " of tick " + std::to_string(tick) + ": error '" +
                              r.answers(i).error().field() + "', not '" + fields[static_cast<std::size_t>(i)] + "'");
          }
          if (r.answers_size() != 6) wrong.push_back(std::to_string(r.answers_size()) + " answers to 6 entries");
        }
        record(kTickEntries, call.finish());
        break;
      }
      case 1: {
        // A good tick, then a whole request refused: a time out of range, a
        // time that goes back, a tick number that does not increase.
        TickCall call(api, Seconds(30));
        const double bad_t[] = {nan, std::numeric_limits<double>::infinity(), 1e308, -1e308, 1.7e15, t - 1.0};
        const std::size_t which = static_cast<std::size_t>(round / 8) % (std::size(bad_t) + 1);
        const bool bad_number = which == std::size(bad_t);
        if (!call.send(tick_request(kScene, v1::PVS_FULL, 5, t, cams(t, 2))) || !call.read(&r))
          wrong.push_back("the good tick was not answered");
        call.send(tick_request(kScene, v1::PVS_FULL, bad_number ? 5 : 6, bad_number ? t : bad_t[which], cams(t, 2)));
        std::size_t drained = 0;
        const grpc::Status st = call.finish(&drained);
        if (drained) wrong.push_back("a bad tick was answered");
        names(st, bad_number ? "tick" : "t");
        record(kTickBadRequest, st);
        break;
      }
      case 2: {
        // Too many viewers in one tick, or too many ids in `left`: refused
        // whole, naming the field. (The limit of viewers kept, 1,024
        // answered and the next refused in its entry, is TickStream's
        // ViewerLimits test: each viewer of a tick takes its turn in the
        // pool's fair queue, so beside the mix a tick of 1,024 viewers takes
        // seconds, however cheap its frames.)
        TickCall call(api, Seconds(30));
        const bool left = (round / 8) % 2 == 1;
        std::vector<TickCam> many = cams(0.0, left ? 1 : 1025);
        for (auto& [id, camera] : many) camera = wall_camera();
        std::vector<std::uint64_t> gone;
        if (left)
          for (std::uint64_t id = 0; id < 1025; ++id) gone.push_back(id);
        call.send(tick_request(kTickSmall, v1::PVS_DELTA, 1, 0.0, many, {}, gone));
        std::size_t drained = 0;
        const grpc::Status st = call.finish(&drained);
        if (drained) wrong.push_back("a tick of 1,025 viewers or left ids was answered");
        names(st, left ? "left" : "viewers");
        record(kTickTooMany, st);
        break;
      }
      case 3: {
        // A flood: 40 ticks of 3 viewers, every 8th with 6 moves, written
        // before any answer is read. Latest tick wins; no move is lost; the
        // last tick is answered. (Moves on every tick would make it a slow
        // crawl: the server reads on only while at most 4 move batches wait,
        // and they wait for the tick that computes.)
        TickCall call(api, Seconds(60));
        constexpr std::uint64_t kTicks = 40;
        std::uint64_t moves_sent = 0, written = 0;
        for (std::uint64_t tick = 1; tick <= kTicks; ++tick) {
          const double at = t + 0.002 * static_cast<double>(tick);
          const std::vector<Move> m = tick % 8 == 1 ? moved(at) : std::vector<Move>{};
          if (!call.send(tick_request(kScene, v1::PVS_DELTA, tick, at, cams(at, 3), m))) break;
          moves_sent += m.size();
          written = tick;
        }
        call.writes_done();
        std::uint64_t answered = 0, skipped = 0, applied = 0, last = 0;
        while (call.read(&r)) {
          if (answered > 0 && r.tick() <= last) wrong.push_back("tick " + std::to_string(r.tick()) + " after " + std::to_string(last));
          ++answered;
          last = r.tick();
          skipped += r.ticks_skipped();
          applied += r.moves_applied();
          if (r.answers_size() != 3) wrong.push_back(std::to_string(r.answers_size()) + " answers to 3 viewers");
          for (const v1::TickAnswer& a : r.answers())
            if (a.has_error()) wrong.push_back("a good entry refused: " + a.error().field());
        }
        const grpc::Status st = call.status();
        if (st.ok()) {
          if (written != kTicks) wrong.push_back("only " + std::to_string(written) + " ticks written");
          if (last != written) wrong.push_back("the last tick answered is " + std::to_string(last));
          if (answered + skipped != written)
            wrong.push_back(std::to_string(answered) + " answered + " + std::to_string(skipped) + " skipped of " +
                            std::to_string(written));
          if (applied != moves_sent)
            wrong.push_back(std::to_string(applied) + " moves applied of " + std::to_string(moves_sent));
        }
        record(kTickFlood, st);
        break;
      }
      case 4: {
        // Cancelled while its tick of 12 viewers computes (or waits), after
        // 0 to 30 ms; every other time after one answer and a second tick.
        TickCall call(api, Seconds(30));
        call.send(tick_request(kScene, v1::PVS_FULL, 1, t, cams(t, 12)));
        if (round % 16 == 4 && call.read(&r)) call.send(tick_request(kScene, v1::PVS_FULL, 2, t + 0.01, cams(t, 12)));
        std::this_thread::sleep_for(std::chrono::milliseconds(10 * ((round / 8) % 4)));
        call.cancel();
        record(kTickCancel, call.finish());
        break;
      }
      case 5: {
        // Five ticks of 8 viewers, never read, left to a 0.3 s deadline: the
        // client gone as far as the server can tell.
        TickCall call(api, Seconds(0.3));
        for (std::uint64_t tick = 1; tick <= 5; ++tick)
          if (!call.send(tick_request(kScene, v1::PVS_DELTA, tick, t + 0.001 * static_cast<double>(tick), cams(t, 8)))) break;
        std::this_thread::sleep_for(std::chrono::milliseconds(400));
        record(kTickVanish, call.finish());
        break;
      }
      case 6: {
        // A good tick with moves, then one whose moves name an unknown id, a
        // static object's, or a bad centre (the last of 6 moves): the stream
        // ends naming moves[5], and that tick is not answered.
        TickCall call(api, Seconds(30));
        if (!call.send(tick_request(kScene, v1::PVS_FULL, 1, t, cams(t, 2), moved(t))) || !call.read(&r))
          wrong.push_back("the good tick was not answered");
        std::vector<Move> bad = moved(t + 0.01);
        const int how = (round / 8) % 4;
        const Move last[] = {{999999, bad[5].center}, {fixed->id, fixed->center}, {bad[5].id, Vec3(nan, 1, 1)},
                             {bad[5].id, Vec3(1e13, 50, 50)}};
        bad[5] = last[how];
        call.send(tick_request(kScene, v1::PVS_FULL, 2, t + 0.01, cams(t, 2), bad));
        std::size_t drained = 0;
        const grpc::Status st = call.finish(&drained);
        if (drained) wrong.push_back("a tick with a bad move was answered");
        names(st, how < 2 ? "moves[5].id" : "moves[5].center");
        record(kTickBadMove, st);
        break;
      }
      default: {
        // A viewer's token: ticks without moves answered, one with moves
        // refused.
        TickCall call(s.server.api(s.options.viewer_token), Seconds(30));
        if (!call.send(tick_request(kScene, v1::PVS_DELTA, 1, t, cams(t, 2))) || !call.read(&r))
          wrong.push_back("a viewer's tick without moves was not answered");
        call.send(tick_request(kScene, v1::PVS_DELTA, 2, t + 0.01, cams(t, 2), moved(t + 0.01)));
        std::size_t drained = 0;
        const grpc::Status st = call.finish(&drained);
        if (drained) wrong.push_back("a viewer's tick with moves was answered");
        record(kTickWrongRole, st);
        break;
      }
    }
  });
}

/// The static scene of the well-behaved tick streams.
SceneDesc tick_static_scene(std::uint64_t seed) {
  test::RandomSceneParams p;
  p.dynamic_fraction = 0.0;
  return test::random_scene(p, seed);
}

// Two well-behaved Tick streams at once: moves of 8 objects of its own and 3
// viewers on the viewer's scene with a simulation's token; 4 viewers on a
// static scene with a viewer's token, checked against GetPvs.
void tick_streams(const Soak& s) {
  GoodTicks moving;
  moving.name = "Tick stream with moves on '" + kScene + "'";
  moving.scene = kScene;
  moving.token = s.options.simulation_token;
  moving.viewers = 3;
  moving.homes = dynamic_homes(s.scene, 8, true);
  moving.camera = soak_tick_camera;
  GoodTicks still;
  still.name = "Tick stream on '" + kTickStatic + "'";
  still.scene = kTickStatic;
  still.token = s.options.viewer_token;
  still.viewers = 4;
  const SceneDesc scene = tick_static_scene(s.options.seed);
  test::CameraPathParams cp;
  cp.frames = 300;
  std::vector<std::vector<Camera>> paths;
  for (int v = 1; v <= still.viewers; ++v)
    paths.push_back(test::random_camera_path(scene, test::mix_seed(s.options.seed, static_cast<std::uint64_t>(v)), cp));
  still.camera = [&paths](int v, std::uint64_t tick, double) {
    const std::vector<Camera>& path = paths[static_cast<std::size_t>(v - 1)];
    return path[tick % path.size()];
  };
  still.check_with_get_pvs = true;
  TickFigures a, b;
  std::thread other([&] { b = run_good_ticks(s, still); });
  a = run_good_ticks(s, moving);
  other.join();
  s.ticks = {std::move(a), std::move(b)};
}

struct Loop {
  const char* name;
  void (*run)(const Soak&);
};
const Loop kLoops[] = {{"bad-times", bad_times},     {"bad-ids", bad_ids},
                       {"floods", floods},           {"view-drops", view_drops},
                       {"simulations", simulations}, {"races", races},
                       {"malformed", malformed},     {"cameras", cameras},
                       {"huge-creates", huge_creates}, {"stream-bursts", stream_bursts},
                       {"tick-streams", tick_streams}, {"hostile-ticks", hostile_ticks},
                       {"mesh-creates", mesh_creates}, {"rebalances", rebalances}};

double mib(long kib) { return static_cast<double>(kib) / 1024.0; }

}  // namespace

std::string soak_tokens_file(const SoakOptions& options) {
  return "admin " + options.admin_token + "\nsimulation " + options.simulation_token + "\nviewer " +
         options.viewer_token + "\n";
}

std::vector<std::string> all_hostile_loops() {
  std::vector<std::string> names;
  for (const Loop& l : kLoops) names.push_back(l.name);
  return names;
}

long HostileKind::calls() const {
  long n = 0;
  for (const auto& [code, count] : codes) n += count;
  return n;
}

std::string code_name(grpc::StatusCode code) {
  static const char* const kNames[] = {
      "OK", "CANCELLED", "UNKNOWN", "INVALID_ARGUMENT", "DEADLINE_EXCEEDED", "NOT_FOUND",
      "ALREADY_EXISTS", "PERMISSION_DENIED", "RESOURCE_EXHAUSTED", "FAILED_PRECONDITION",
      "ABORTED", "OUT_OF_RANGE", "UNIMPLEMENTED", "INTERNAL", "UNAVAILABLE", "DATA_LOSS",
      "UNAUTHENTICATED"};
  const int c = static_cast<int>(code);
  return c >= 0 && c <= 16 ? kNames[c] : "code " + std::to_string(c);
}

SoakResult run_soak(const ServerProcess& server, const SoakOptions& options) {
  SoakResult result;
  for (const std::string& name : options.mix) result.mix += (result.mix.empty() ? "" : ",") + name;
  const SceneDesc scene = lattice_scene(options.objects, options.grid, options.seed);
  {
    const Api admin = server.api(options.admin_token);
    v1::SceneDescription d, still;
    to_proto(scene, &d);
    to_proto(tick_static_scene(options.seed), &still);
    for (const grpc::Status& st :
         {admin.create_scene(kScene, d), admin.create_scene_json(kRace, wall_scene_json()),
          admin.create_scene(kTickStatic, still), admin.create_scene_json(kTickSmall, wall_scene_json())}) {
      if (!st.ok()) {
        ADD_FAILURE() << "the soak's scenes: " << code_name(st.error_code()) << " "
                      << st.error_message();
        return result;
      }
    }
  }
  Tally tally;
  std::atomic<bool> stop{false}, stop_sampling{false};
  const Soak s{server, options, scene, tally, stop, Clock::now(), result.ticks};
  long rss_last = server.rss_kib();
  long rss_peak = rss_last;
  result.rss_start_mib = mib(rss_last);
  std::thread sampler([&] {
    while (!stop_sampling.load()) {
      std::this_thread::sleep_for(options.sample_period);
      const long kib = server.rss_kib();
      if (kib < 0) continue;
      rss_last = kib;
      rss_peak = std::max(rss_peak, kib);
      ++result.rss_samples;
    }
  });
  std::thread viewer([&] { result.viewer = run_viewer(s); });
  std::vector<std::thread> mix;
  for (const Loop& loop : kLoops) {
    if (std::find(options.mix.begin(), options.mix.end(), loop.name) != options.mix.end())
      mix.emplace_back(loop.run, std::cref(s));
  }
  if (mix.size() != options.mix.size()) ADD_FAILURE() << "unknown loops in " << result.mix;

  std::this_thread::sleep_until(s.start +
                                std::chrono::duration_cast<Clock::duration>(options.duration));
  stop.store(true);
  for (std::thread& t : mix) t.join();
  viewer.join();
  result.seconds = std::chrono::duration<double>(Clock::now() - s.start).count();

  v1::GetPvsResponse r;
  const grpc::Status fresh = server.api(options.admin_token).get_pvs(kScene, 0.0, orbit(0), &r);
  result.answering_at_end = fresh.ok();
  result.answering_status = code_name(fresh.error_code()) +
                            (fresh.ok() ? "" : ": " + fresh.error_message());
  // Let the server free what the mix's calls left, then take the last sample.
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  stop_sampling.store(true);
  sampler.join();
  result.rss_peak_mib = mib(rss_peak);
  result.rss_end_mib = mib(rss_last);
  result.hostile = tally.kinds();
  return result;
}

}  // namespace voxvis::servertest
