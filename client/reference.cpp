// reference.cpp — see reference.h.
#include "reference.h"

#include <algorithm>
#include <iterator>
#include <thread>

#include "voxvis/raycast.h"

namespace voxvis::cli {

bool parse_reference(const std::string& text, Reference* out, std::string* message) {
  if (text == "auto") *out = Reference::Auto;
  else if (text == "egl") *out = Reference::Egl;
  else if (text == "raycast") *out = Reference::Raycast;
  else {
    *message = "unknown reference '" + text + "' (known: auto, egl, raycast)";
    return false;
  }
  return true;
}

Reference resolve_reference(Reference reference, const render::ContextOptions& ctx) {
  if (reference == Reference::Auto && (ctx.device >= 0 || ctx.platform != render::Platform::Auto))
    return Reference::Egl;
  return reference;
}

bool parse_reference_flags(const std::string& reference, const EglArgs& egl, Reference* out,
                           render::ContextOptions* ctx, FormatError* error) {
  std::string message;
  if (!parse_reference(reference, out, &message)) {
    *error = FormatError{"", 0, "--reference", message};
    return false;
  }
  if (!render::parse_platform(egl.platform, &ctx->platform, &message)) {
    *error = FormatError{"", 0, "--egl-platform", message};
    return false;
  }
  if (egl.device < -1) {
    *error = FormatError{"", 0, "--egl-device", "must be >= 0"};
    return false;
  }
  ctx->device = egl.device;
  if (!render::parse_id_readback(egl.id_readback, &ctx->id_readback, &message)) {
    *error = FormatError{"", 0, "--id-readback", message};
    return false;
  }
  if (egl.query_readback != "batch" && egl.query_readback != "each") {
    *error = FormatError{"", 0, "--query-readback", "unknown read-back '" + egl.query_readback +
                                                        "' (known: batch, each)"};
    return false;
  }
  ctx->batch_queries = egl.query_readback == "batch";
  *out = resolve_reference(*out, *ctx);
  return true;
}

bool raycast_visible(const std::vector<ObjectDesc>& objects, const Camera& cam, int width, int height,
                     std::vector<ObjectId>* out, render::VisibleStats* stats, std::string* error) {
  raycast::ViewBasis basis;
  if (!raycast::make_basis(cam, &basis)) {
    *error = "camera: defines no frustum";
    return false;
  }
  raycast::CastStats cs;
  *out = raycast::visible_objects(objects, cam, raycast::pixel_centres(width, height), {}, &cs);
  *stats = render::VisibleStats{};
  stats->in_frustum = static_cast<std::uint32_t>(cs.in_frustum);
  stats->upload_ms = cs.build_ms;
  stats->draw_ms = cs.cast_ms;
  return true;
}

bool confirm_misses(render::Renderer* renderer, const std::vector<ObjectDesc>& objects, const Camera& cam, int width,
                    int height, bool ids_current, const std::vector<ObjectId>& visible,
                    const std::vector<ObjectId>& pvs, std::vector<ObjectId>* missed, std::vector<ObjectId>* dismissed,
                    std::string* error) {
  missed->clear();
  dismissed->clear();
  std::vector<ObjectId> sighted;
  std::set_difference(visible.begin(), visible.end(), pvs.begin(), pvs.end(), std::back_inserter(sighted));
  if (renderer == nullptr || sighted.empty()) {
    *missed = std::move(sighted);
    return true;
  }
  if (!ids_current) {
    std::vector<ObjectId> shown;
    render::VisibleStats id_pass;
    if (!renderer->visible(objects, cam, render::VisibleOptions{width, height, render::Method::Ids}, nullptr, &shown,
                           &id_pass, error))
      return false;
  }
  raycast::confirm_near_pixels(objects, cam, width, height, renderer->last_ids(), sighted, missed, dismissed);
  if (!ids_current && !dismissed->empty()) {
    // The id pass keeps one object of a depth tie: what it did not show is
    // tried at every pixel.
    const std::vector<ObjectId> every_pixel;
    std::vector<ObjectId> tried, confirmed;
    tried.swap(*dismissed);
    raycast::confirm_near_pixels(objects, cam, width, height, every_pixel, tried, &confirmed, dismissed);
    missed->insert(missed->end(), confirmed.begin(), confirmed.end());
    std::sort(missed->begin(), missed->end());
  }
  return true;
}

std::string raycast_summary() {
  const unsigned threads = std::max(1u, std::thread::hardware_concurrency());
  return "CPU ray caster, " + std::to_string(threads) + (threads == 1 ? " thread" : " threads");
}

}  // namespace voxvis::cli
