// engine_check.cpp — see engine_check.h.
#include "engine_check.h"

#include <algorithm>
#include <cmath>
#include <iterator>
#include <sstream>

#include "scenes.h"

namespace voxvis::test {
namespace {

using Ids = std::vector<ObjectId>;

bool sorted_unique(const Ids& v) {
  return std::adjacent_find(v.begin(), v.end(), [](ObjectId a, ObjectId b) { return a >= b; }) ==
         v.end();
}

}  // namespace

std::string check_stats(const FrameStats& s, std::size_t objects) {
  std::ostringstream err;
  if (!std::isfinite(s.time_us) || s.time_us < 0.0) err << "stats.time_us=" << s.time_us << "; ";
  if (s.pvs_size > objects) err << "stats.pvs_size=" << s.pvs_size << " > objects; ";
  if (s.tbvs_active > objects) err << "stats.tbvs_active=" << s.tbvs_active << " > objects; ";
  if (s.tbvs_created > objects) err << "stats.tbvs_created=" << s.tbvs_created << " > objects; ";
  if (s.tbvs_revealed > objects) err << "stats.tbvs_revealed=" << s.tbvs_revealed << " > objects; ";
  if (s.tbvs_expired > objects) err << "stats.tbvs_expired=" << s.tbvs_expired << " > objects; ";
  if (s.objects_discretized > objects) {
    err << "stats.objects_discretized=" << s.objects_discretized << " > objects; ";
  }
  if (s.outside_tested > 2 * objects) err << "stats.outside_tested=" << s.outside_tested << "; ";
  // The split of time_us: parts of it, measured inside it.
  for (const double part : {s.traverse_us, s.render_us, s.retest_us})
    if (!std::isfinite(part) || part < 0.0) err << "a part of time_us is " << part << "; ";
  if (s.render_us > s.traverse_us + 1e-6 || s.traverse_us + s.retest_us > s.time_us + 1e-6)
    err << "time split render " << s.render_us << " traverse " << s.traverse_us << " retest " << s.retest_us
        << " over time_us " << s.time_us << "; ";
  return err.str();
}

std::string check_frame(const std::string& label, int frame, const std::vector<ObjectDesc>& objects,
                        const Camera& cam, const FrameResult& r, const RaySampling& sampling) {
  std::ostringstream err;
  Ids all;
  Ids dynamic;
  for (const ObjectDesc& o : objects) {
    all.push_back(o.id);
    if (o.dynamic) dynamic.push_back(o.id);
  }
  std::sort(all.begin(), all.end());
  std::sort(dynamic.begin(), dynamic.end());

  const Ids visible = visible_objects(objects, cam, sampling);
  const Ids missed = missing_ids(r.pvs, visible);
  if (!missed.empty()) {
    err << "MISS: " << label << " frame=" << frame << "\n  " << describe(cam) << "\n  missed "
        << describe_ids(missed) << " (pvs " << r.pvs.size() << ", visible " << visible.size()
        << ", sampling " << sampling.cols << "x" << sampling.rows << " seed " << sampling.seed
        << (sampling.corners ? " +corners" : "") << ")\n";
    std::size_t shown = 0;
    for (ObjectId id : missed) {
      for (const ObjectDesc& o : objects) {
        if (o.id == id && shown < 12) {
          err << "  " << describe(o) << "\n";
          ++shown;
        }
      }
    }
  }
  const std::string where = " (" + label + " frame=" + std::to_string(frame) + ")\n";
  if (!sorted_unique(r.pvs)) err << "pvs not ascending and unique" << where;
  if (!sorted_unique(r.wake)) err << "wake not ascending and unique" << where;
  if (const Ids unknown = missing_ids(all, r.pvs); !unknown.empty()) {
    err << "pvs holds unknown ids " << describe_ids(unknown) << where;
  }
  if (r.stats.pvs_size != r.pvs.size()) {
    err << "stats.pvs_size=" << r.stats.pvs_size << " != pvs.size()=" << r.pvs.size() << where;
  }
  if (const std::string s = check_stats(r.stats, objects.size()); !s.empty()) err << s << where;
  if (const Ids bad = missing_ids(dynamic, r.wake); !bad.empty()) {
    err << "wake holds non-dynamic ids " << describe_ids(bad) << where;
  }
  Ids pvs_dynamic;
  std::set_intersection(r.pvs.begin(), r.pvs.end(), dynamic.begin(), dynamic.end(),
                        std::back_inserter(pvs_dynamic));
  if (const Ids not_woken = missing_ids(r.wake, pvs_dynamic); !not_woken.empty()) {
    err << "dynamic PVS members missing from wake " << describe_ids(not_woken) << where;
  }
  return err.str();
}

EngineHarness::EngineHarness(const SceneDesc& desc, const SceneOptions& options, std::string label)
    : label_(std::move(label)), objects_(desc.objects) {
  status_ = Scene::create(desc, options, &scene_);
  if (status_.ok && scene_) viewer_ = scene_->add_viewer();
  if (status_.ok && !scene_) status_ = Status::Error("scene", "Scene::create returned ok but no scene");
}

Status EngineHarness::move(double t, const std::vector<Move>& moves, MoveReport* report) {
  Status s = scene_->apply_moves(t, moves, report);
  if (s.ok) apply_moves_to(&objects_, moves);
  return s;
}

std::string EngineHarness::frame_viewer(ViewerId viewer, const Camera& cam, double t,
                                        const RaySampling* sampling) {
  last_ = FrameResult{};
  const int f = frames_++;
  const Status s = scene_->frame(viewer, cam, t, scratch_, &last_);
  if (!s.ok) {
    return "Scene::frame refused a valid camera: " + s.str() + " (" + label_ + " frame=" +
           std::to_string(f) + ")\n  " + describe(cam) + "\n";
  }
  // 96x96 jittered rays (fewer when VOXVIS_TEST_SCALE < 1, e.g. under
  // sanitizers, down to 48x48) plus every cell corner.
  RaySampling def;
  const int n = static_cast<int>(std::lround(96.0 * std::sqrt(std::min(1.0, test_scale()))));
  def.cols = def.rows = std::max(48, n);
  def.corners = true;
  def.seed = mix_seed(0x9e3779b9ULL, static_cast<std::uint64_t>(f));
  return check_frame(label_, f, objects_, cam, last_, sampling ? *sampling : def);
}

}  // namespace voxvis::test
