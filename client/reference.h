// reference.h — where `voxvis report` and `voxvis verify` take the exactly
// visible set of a frame from: the headless renderer (EGL, voxvis/render.h)
// at W x H, or the CPU ray caster (voxvis/raycast.h) through the same pixel
// centres where no EGL is available (docs/accuracy.md, docs/verify.md).
#pragma once

#include <string>
#include <vector>

#include "cli.h"
#include "voxvis/format.h"
#include "voxvis/render.h"
#include "voxvis/types.h"

namespace voxvis::cli {

enum class Reference {
  Auto,     ///< EGL when a context starts, else the ray caster.
  Egl,      ///< The headless renderer; no EGL is an error.
  Raycast,  ///< The CPU ray caster; EGL is not needed for the reference.
};

/// "auto", "egl" or "raycast"; on error sets `message`.
bool parse_reference(const std::string& text, Reference* out, std::string* message);

/// Auto with an EGL device or platform named (not auto) is Egl: whoever
/// names one wants EGL, and a typo must not fall back quietly.
Reference resolve_reference(Reference reference, const render::ContextOptions& ctx);

/// The flags both commands share: --reference (resolved as above), and the
/// EGL flags (--egl-platform, --egl-device, --id-readback, --query-readback)
/// into `ctx`. False, with `error` naming the flag, on a bad value.
bool parse_reference_flags(const std::string& reference, const EglArgs& egl, Reference* out,
                           render::ContextOptions* ctx, FormatError* error);

/// The ray caster's exactly visible set at width x height: the first hits of
/// the rays through the pixel centres (every object of a tie), ascending.
/// `stats` gets its costs in the renderer's terms: in_frustum, the objects
/// that may be hit; upload_ms, culling and building the hierarchy; draw_ms,
/// casting. False, with `error` set, for a camera that defines no frustum.
bool raycast_visible(const std::vector<ObjectDesc>& objects, const Camera& cam, int width, int height,
                     std::vector<ObjectId>* out, render::VisibleStats* stats, std::string* error);

/// "CPU ray caster, N threads" for the report's and verify's header lines.
std::string raycast_summary();

/// The one definition of a miss that `verify` and `report` share: of the
/// objects the reference showed (`visible`) that `pvs` lacks, those
/// visible by the definition. From the ray caster every one (it casts in
/// double precision, docs/verify.md). From EGL, whose single precision may
/// show at a pixel centre what only an edge reveals, a sighting counts when
/// the double-precision cones around one of the pixels showing it see it
/// first (raycast::confirm_near_pixels); the others go to `dismissed`. The
/// pixels are those of the renderer's last id image when `ids_current` (it
/// just drew this frame by Method::Ids), else of an id pass drawn here;
/// what that pass does not confirm (an object left out of a depth tie) is
/// tried at every pixel. Ascending ids; false, with `error`, when the id
/// pass fails.
bool confirm_misses(render::Renderer* renderer, const std::vector<ObjectDesc>& objects, const Camera& cam, int width,
                    int height, bool ids_current, const std::vector<ObjectId>& visible,
                    const std::vector<ObjectId>& pvs, std::vector<ObjectId>* missed, std::vector<ObjectId>* dismissed,
                    std::string* error);

}  // namespace voxvis::cli
