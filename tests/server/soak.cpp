#include "soak.h"

#include "extreme_cameras.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <filesystem>
#include <functional>
#include <limits>
#include <mutex>
#include <optional>
#include <random>
#include <sstream>
#include <thread>

namespace voxvis::servertest {
namespace {

using Clock = std::chrono::steady_clock;
using C = grpc::StatusCode;

const std::string kScene = "soak";
const std::string kRace = "race";

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
const char* const kBurst = "View burst of new streams";

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

  /// Seconds since the start: the times the hostile calls use.
  double now_t() const { return std::chrono::duration<double>(Clock::now() - start).count(); }

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
  const Api api = s.server.api();
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
  const Api api = s.server.api();
  const double bad[] = {1e308, -1e308, std::numeric_limits<double>::quiet_NaN(), 1.7e15,
                        std::numeric_limits<double>::infinity()};
  s.loop(1, [&](int) {
    v1::GetPvsResponse r;
    for (double t : bad) s.tally.record(kBadTime, api.get_pvs(kScene, t, orbit(0), &r));
  });
}

void bad_ids(const Soak& s) {
  s.tally.expect(kBadId, {C::INVALID_ARGUMENT});
  const Api api = s.server.api();
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
    const Api api = s.server.api();
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
    const Api api = s.server.api();
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
    const Api api = s.server.api();
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
  const Api api = s.server.api();
  const Api other = s.server.api();
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
      frame = s.server.api().get_pvs(kRace, 0.0, wall_camera(), &r);
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
                                                &response, Seconds(5)));
    s.tally.record(kMalformedView, generic_bidi(channel, "/voxvis.v1.Visibility/View", bytes,
                                                &responses, Seconds(5)));
  });
}

// Cameras at the documented bounds and beyond them, by GetPvs and on View
// streams: the accepted ones are answered, the others refused naming the
// field; none may take the server down.
void cameras(const Soak& s) {
  s.tally.expect(kExtremeCamera, {C::OK});
  s.tally.expect(kCameraBeyond, {C::INVALID_ARGUMENT});
  s.tally.expect(kExtremeView, {C::OK});
  const Api api = s.server.api();
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
    const Api admin = s.server.api();
    grpc::ClientContext ctx;
    admin.prepare(&ctx, round % 2 ? Seconds(0.3) : Seconds(30));
    v1::CreateSceneRequest req;
    req.set_scene_id("huge");
    *req.mutable_description() = huge;
    v1::SceneInfo info;
    s.tally.record(kHugeCreate, admin.stub().CreateScene(&ctx, req, &info));
  });
}

// A hundred new View streams at once over two new connections, each
// sending one frame: every one answered.
void stream_bursts(const Soak& s) {
  s.tally.expect(kBurst, {C::OK});
  s.loop(100, [&](int) {
    const Api a = s.server.api(), b = s.server.api();
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

struct Loop {
  const char* name;
  void (*run)(const Soak&);
};
const Loop kLoops[] = {{"bad-times", bad_times},     {"bad-ids", bad_ids},
                       {"floods", floods},           {"view-drops", view_drops},
                       {"simulations", simulations}, {"races", races},
                       {"malformed", malformed},     {"cameras", cameras},
                       {"huge-creates", huge_creates}, {"stream-bursts", stream_bursts}};

double mib(long kib) { return static_cast<double>(kib) / 1024.0; }

}  // namespace

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
    const Api admin = server.api();
    v1::SceneDescription d;
    to_proto(scene, &d);
    for (const grpc::Status& st :
         {admin.create_scene(kScene, d), admin.create_scene_json(kRace, wall_scene_json())}) {
      if (!st.ok()) {
        ADD_FAILURE() << "the soak's scenes: " << code_name(st.error_code()) << " "
                      << st.error_message();
        return result;
      }
    }
  }
  Tally tally;
  std::atomic<bool> stop{false}, stop_sampling{false};
  const Soak s{server, options, scene, tally, stop, Clock::now()};
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
  const grpc::Status fresh = server.api().get_pvs(kScene, 0.0, orbit(0), &r);
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
