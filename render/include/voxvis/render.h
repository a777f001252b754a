// voxvis/render.h — the headless renderer: an OpenGL 4.x core context through
// EGL with no window system (the EGL device platform first, Mesa's surfaceless
// platform as the fallback), and the exactly visible set of a frame at pixel
// level, for `voxvis verify`, the server's verify mode and the accuracy report.
//
// Definition of "visible" used here (docs/verify.md): an object is visible at
// W x H when it is the first object hit by the ray through the centre of some
// pixel, with the conventions of the CPU ray caster (voxvis/raycast.h): balls
// and boxes are solids (closed balls and axis-aligned boxes, drawn exactly,
// not tessellated), meshes are surfaces (their triangles, both faces, placed
// by centre, rotation and scale as voxvis/mesh.h says, drawn as such: the
// rasterizer's fill rule lets no pixel centre through between two triangles
// that share an edge), each ray's hits are clipped to [near, far] (a ball or
// box that contains the eye is hit at depth `near`; a mesh cut by the near
// plane shows what lies inside it), pixel (i, j) samples the image point
// x = -1 + (2i+1)/W, y = -1 + (2j+1)/H. Depths are computed in single
// precision relative to the eye, so objects entered at depths within about
// 1e-6 of each other may be told apart differently from a double-precision
// caster (ties), and an object that covers no pixel centre is not visible at
// that resolution however close it comes. Rounding may also let a pixel
// centre's ray that crosses an edge where objects meet through to what lies
// behind them: seen along the edge only (rays of measure zero), which is not
// visible by the definition (voxvis/raycast.h). `voxvis verify` and the
// server's verify mode confirm a sighting in double precision before they
// count it as a miss (raycast::confirm_near_pixels; docs/verify.md).
//
// A Renderer owns its context; the EGL display under it is initialised once
// and kept for the life of the process. It keeps each mesh's vertex and
// index buffers on the GPU from frame to frame (found by the mesh's address
// while the mesh lives; meshes are immutable), so a mesh is uploaded once. A Renderer may be created on one
// thread and used on another, but by one thread at a time: every call makes
// its context current on the calling thread.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "voxvis/types.h"

namespace voxvis::render {

/// Which EGL platform provides the display.
enum class Platform {
  Auto,         ///< The device platform, else surfaceless.
  Device,       ///< EGL_EXT_platform_device: a GPU, or Mesa's software device.
  Surfaceless,  ///< EGL_MESA_platform_surfaceless.
};

/// "auto", "device" or "surfaceless"; on error sets `message`.
bool parse_platform(const std::string& text, Platform* out, std::string* message);
const char* platform_name(Platform p);

/// How Method::Ids reads a frame's visible set back from the GPU.
enum class IdReadback {
  /// Set on a GPU; Image on a software renderer (llvmpipe), whose image is
  /// in the CPU's memory already: a copy of it costs about what a shader
  /// pass over it does (0.87 against 1.0 ms at 640x360, docs/verify.md).
  Auto,
  /// A compute pass marks the ids the image holds in a buffer of flags, and
  /// only the flags come back: 4 bytes an object in the frustum, where the
  /// image is 4 bytes a pixel. Needs OpenGL 4.3 (else Image).
  Set,
  /// The whole id image read back (glReadPixels), the set taken from it.
  Image,
};

bool parse_id_readback(const std::string& text, IdReadback* out, std::string* message);
const char* id_readback_name(IdReadback r);

struct ContextOptions {
  Platform platform = Platform::Auto;
  IdReadback id_readback = IdReadback::Auto;
  /// Occlusion queries' results read a round at once: the queries write
  /// them into a query buffer object on the GPU (OpenGL 4.4) and one read
  /// brings them back. False: one glGetQueryObjectuiv a query (a round trip
  /// each on a GPU), kept for comparison.
  bool batch_queries = true;
  /// EGL device index on the device platform, as eglQueryDevicesEXT lists
  /// them (--egl-device N); -1: the first device that is not a software
  /// renderer, else the software one. The device platform is taken when the
  /// client extensions hold EGL_EXT_platform_device and EGL_EXT_device_base
  /// or EGL_EXT_device_enumeration (render/src/egl_select.h).
  int device = -1;
};

/// What the context runs on.
struct ContextInfo {
  Platform platform = Platform::Device;  ///< The one chosen (never Auto).
  int device = -1;                       ///< Index of the EGL device; -1 on surfaceless.
  int devices = 0;                       ///< EGL devices found.
  bool software = false;                 ///< Mesa's software device (llvmpipe).
  std::string gl_renderer;               ///< GL_RENDERER, e.g. "llvmpipe (LLVM 15.0.6, 256 bits)".
  std::string gl_version;                ///< GL_VERSION.
  bool id_set_on_gpu = false;            ///< Method::Ids reads the set, not the image (IdReadback).
  bool query_buffer = false;             ///< Query results read a round at once (batch_queries).
  /// Why this platform and device: "the first of 2 devices that is not a
  /// software renderer", "--egl-device 1 of 2", "no device platform: ...".
  std::string why;
  int max_size = 0;                      ///< Largest width or height a frame may have, pixels.
  std::string summary() const;           ///< One line for logs.
};

/// How the visible set is read from the GPU.
enum class Method {
  /// One pass draws every object in the frustum into an id buffer, read back
  /// once: the first hit at every pixel centre (one object per pixel on a
  /// depth tie, the first drawn: balls and boxes in the order given, then
  /// meshes).
  Ids,
  /// A depth pass of every object in the frustum, then one
  /// GL_ANY_SAMPLES_PASSED query per candidate (all issued before any result
  /// is read): a candidate is visible when some pixel centre's first-hit
  /// depth equals its own (every object of a depth tie).
  Queries,
};

bool parse_method(const std::string& text, Method* out, std::string* message);

/// Parses "WIDTHxHEIGHT" in pixels (each >= 1; the context's limit is
/// checked when rendering); on error sets `message`.
bool parse_resolution(const std::string& text, int* width, int* height, std::string* message);
const char* method_name(Method m);

struct VisibleOptions {
  int width = 640;
  int height = 360;
  Method method = Method::Ids;
};

/// Costs of one call, wall-clock milliseconds on the calling thread.
struct VisibleStats {
  std::uint32_t in_frustum = 0;  ///< Objects the CPU's frustum test kept and drew.
  std::uint32_t queries = 0;     ///< Occlusion queries issued (Method::Queries).
  double upload_ms = 0.0;        ///< Frustum test and instance upload.
  double draw_ms = 0.0;          ///< Issuing the depth/id pass.
  double query_ms = 0.0;         ///< Issuing the queries.
  double read_ms = 0.0;          ///< Waiting for and reading the results.
};

struct Level;        // voxvis/refine.h
struct RefineStats;  // voxvis/refine.h
struct CostModel;    // voxvis/refine.h

class Renderer {
 public:
  /// Creates a context and its framebuffer resources. On failure returns
  /// null and sets `error` to what is missing (no EGL implementation, no
  /// device, no OpenGL 4.2 core context, ...).
  static std::unique_ptr<Renderer> create(const ContextOptions& options, std::string* error);
  ~Renderer();
  Renderer(const Renderer&) = delete;
  Renderer& operator=(const Renderer&) = delete;

  const ContextInfo& info() const;

  /// The ids of the objects visible under `cam` at the options' resolution,
  /// ascending. `candidates` (ascending ids; null: every object) limits which
  /// objects are reported; every object is drawn as an occluder either way.
  /// Returns false and sets `error` for a camera that defines no frustum, a
  /// resolution below 1 or above info().max_size, or a GL failure.
  bool visible(const std::vector<ObjectDesc>& objects, const Camera& cam, const VisibleOptions& options,
               const std::vector<ObjectId>* candidates, std::vector<ObjectId>* out,
               VisibleStats* stats, std::string* error);

  /// Refines `pvs` (ascending ids of `objects`) by `level` at width x
  /// height: `out` is a subset of `pvs`, ascending (voxvis/refine.h says
  /// what each level keeps). Errors as visible()'s.
  bool refine(const Level& level, const std::vector<ObjectDesc>& objects, const Camera& cam, int width,
              int height, const std::vector<ObjectId>& pvs, std::vector<ObjectId>* out, RefineStats* stats,
              std::string* error);

  /// Forgets what the refinement levels keep between frames (ternary's tree,
  /// near-optimal's last states): the next frame starts afresh.
  void reset_refinement();

  /// Near-optimal's cost model of this context's GPU: loaded from
  /// `path` when it holds one for this device (GL_RENDERER and GL_VERSION),
  /// else measured (a fraction of a second) and saved there (path empty:
  /// not kept). Measured once per Renderer; later calls return it. `note`
  /// says where it came from ("loaded from ...", "calibrated in ... ms,
  /// saved to ..." or why it could not be saved); false only on a GL error.
  bool cost_model(const std::string& path, CostModel* out, std::string* note, std::string* error);
  /// Uses `model` from now on instead (neither measured nor saved).
  void set_cost_model(const CostModel& model);

  /// The id at every pixel of the last Method::Ids call (row 0 at the bottom,
  /// 0 where no object is hit), width * height values; empty once the
  /// renderer has drawn again (visible() or refine()). The image is read
  /// back from the GPU here, on first use: visible() itself reads back only
  /// the set of ids (a flag an object), gathered on the GPU (OpenGL 4.3;
  /// the whole image on 4.2).
  const std::vector<ObjectId>& last_ids() const;

  /// The internals (render/src/renderer_impl.h), for the passes' own files.
  struct Impl;

 private:
  explicit Renderer(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace voxvis::render
