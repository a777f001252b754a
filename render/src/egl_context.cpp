// egl_context.cpp — see egl_context.h.
#include "egl_context.h"

#include "egl_select.h"

#include <cstdio>
#include <cstring>
#include <mutex>
#include <set>
#include <string>
#include <vector>

#include <EGL/eglext.h>
#define GL_GLEXT_PROTOTYPES 1
#include <GL/glcorearb.h>

namespace voxvis::render::detail {
namespace {

const char* egl_error_name(EGLint e) {
  switch (e) {
    case EGL_SUCCESS: return "EGL_SUCCESS";
    case EGL_NOT_INITIALIZED: return "EGL_NOT_INITIALIZED";
    case EGL_BAD_ACCESS: return "EGL_BAD_ACCESS";
    case EGL_BAD_ALLOC: return "EGL_BAD_ALLOC";
    case EGL_BAD_ATTRIBUTE: return "EGL_BAD_ATTRIBUTE";
    case EGL_BAD_CONFIG: return "EGL_BAD_CONFIG";
    case EGL_BAD_CONTEXT: return "EGL_BAD_CONTEXT";
    case EGL_BAD_CURRENT_SURFACE: return "EGL_BAD_CURRENT_SURFACE";
    case EGL_BAD_DISPLAY: return "EGL_BAD_DISPLAY";
    case EGL_BAD_MATCH: return "EGL_BAD_MATCH";
    case EGL_BAD_NATIVE_PIXMAP: return "EGL_BAD_NATIVE_PIXMAP";
    case EGL_BAD_NATIVE_WINDOW: return "EGL_BAD_NATIVE_WINDOW";
    case EGL_BAD_PARAMETER: return "EGL_BAD_PARAMETER";
    case EGL_BAD_SURFACE: return "EGL_BAD_SURFACE";
    case EGL_CONTEXT_LOST: return "EGL_CONTEXT_LOST";
    default: return "unknown EGL error";
  }
}

std::string egl_failure(const std::string& what) {
  char code[16];
  const EGLint e = eglGetError();
  std::snprintf(code, sizeof code, "0x%04x", static_cast<unsigned>(e));
  return what + " failed (" + egl_error_name(e) + ", " + code + ")";
}

/// EGL displays are per process and shared by every context on them. Each
/// is initialised once and kept for the life of the process: eglTerminate
/// would end it for every other renderer, and it unloads Mesa's driver, which
/// leaves a few hundred bytes behind each time (seen by LeakSanitizer as
/// leaks from an unknown module); initialising again costs 6-36 ms.
bool initialise_display(EGLDisplay dpy, std::string* error) {
  static std::mutex mu;
  static std::set<EGLDisplay>* ready = new std::set<EGLDisplay>;  // Outlives every context.
  std::lock_guard<std::mutex> lock(mu);
  if (ready->count(dpy)) return true;
  EGLint major = 0, minor = 0;
  if (!eglInitialize(dpy, &major, &minor)) {
    *error = egl_failure("eglInitialize");
    return false;
  }
  ready->insert(dpy);
  return true;
}

struct DeviceChoice {
  EGLDisplay display = EGL_NO_DISPLAY;
  int index = -1;
  int count = 0;
  bool software = false;
  std::string why;  // Why this platform and device.
};

bool open_device(int wanted, DeviceChoice* out, std::string* error) {
  const char* client = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
  if (!device_platform_offered(client, error)) return false;
  auto query_devices = reinterpret_cast<PFNEGLQUERYDEVICESEXTPROC>(eglGetProcAddress("eglQueryDevicesEXT"));
  auto query_string =
      reinterpret_cast<PFNEGLQUERYDEVICESTRINGEXTPROC>(eglGetProcAddress("eglQueryDeviceStringEXT"));
  auto platform_display =
      reinterpret_cast<PFNEGLGETPLATFORMDISPLAYEXTPROC>(eglGetProcAddress("eglGetPlatformDisplayEXT"));
  if (query_devices == nullptr || query_string == nullptr || platform_display == nullptr) {
    *error = "the EGL device platform's entry points are missing";
    return false;
  }
  EGLint count = 0;
  if (!query_devices(0, nullptr, &count)) {
    *error = egl_failure("eglQueryDevicesEXT");
    return false;
  }
  std::vector<EGLDeviceEXT> devices(static_cast<std::size_t>(count));
  if (count > 0 && !query_devices(count, devices.data(), &count)) {
    *error = egl_failure("eglQueryDevicesEXT");
    return false;
  }
  devices.resize(static_cast<std::size_t>(count));
  out->count = count;
  std::vector<std::string> extensions;
  for (const EGLDeviceEXT d : devices) {
    const char* e = query_string(d, EGL_EXTENSIONS);
    extensions.emplace_back(e != nullptr ? e : "");
  }
  DevicePick pick;
  if (!choose_device(extensions, wanted, &pick, error)) return false;
  const EGLDeviceEXT dev = devices[static_cast<std::size_t>(pick.index)];
  out->display = platform_display(EGL_PLATFORM_DEVICE_EXT, dev, nullptr);
  if (out->display == EGL_NO_DISPLAY) {
    *error = egl_failure("eglGetPlatformDisplayEXT(EGL_PLATFORM_DEVICE_EXT, device " + std::to_string(pick.index) + ")");
    return false;
  }
  out->index = pick.index;
  out->software = pick.software;
  out->why = pick.why;
  return true;
}

bool open_surfaceless(DeviceChoice* out, std::string* error) {
  const char* client = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
  if (!surfaceless_offered(client, error)) return false;
  auto platform_display =
      reinterpret_cast<PFNEGLGETPLATFORMDISPLAYEXTPROC>(eglGetProcAddress("eglGetPlatformDisplayEXT"));
  if (platform_display == nullptr) {
    *error = "eglGetPlatformDisplayEXT is missing";
    return false;
  }
  out->display = platform_display(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr);
  if (out->display == EGL_NO_DISPLAY) {
    *error = egl_failure("eglGetPlatformDisplayEXT(EGL_PLATFORM_SURFACELESS_MESA)");
    return false;
  }
  return true;
}

}  // namespace

std::unique_ptr<EglContext> EglContext::create(const ContextOptions& options, ContextInfo* info,
                                               std::string* error) {
  // libEGL (glvnd) loads a vendor library; with none, even the client
  // extension string is missing. Checked first so that the message says so.
  const char* client = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
  if (client == nullptr || !has_extension(client, "EGL_EXT_platform_base")) {
    *error = "no EGL implementation found (libEGL has no vendor with EGL_EXT_platform_base: install "
             "libegl-mesa0 and libgl1-mesa-dri, or a GPU driver's EGL; check "
             "__EGL_VENDOR_LIBRARY_FILENAMES if set)";
    return nullptr;
  }
  DeviceChoice choice;
  std::string device_error, surfaceless_error;
  bool opened = false;
  if (options.platform != Platform::Surfaceless) {
    opened = open_device(options.device, &choice, &device_error);
    if (opened) info->platform = Platform::Device;
  }
  if (!opened && options.platform != Platform::Device) {
    if (options.device >= 0) {
      *error = "--egl-device " + std::to_string(options.device) + ": " + device_error;
      return nullptr;
    }
    opened = open_surfaceless(&choice, &surfaceless_error);
    if (opened) {
      info->platform = Platform::Surfaceless;
      choice.why = options.platform == Platform::Surfaceless ? "asked for" : "no device platform: " + device_error;
    }
  }
  if (!opened) {
    if (options.platform == Platform::Device)
      *error = device_error;
    else if (options.platform == Platform::Surfaceless)
      *error = surfaceless_error;
    else
      *error = "no EGL display: device platform: " + device_error + "; surfaceless platform: " + surfaceless_error;
    return nullptr;
  }
  info->device = info->platform == Platform::Device ? choice.index : -1;
  info->devices = choice.count;
  info->software = choice.software;
  info->why = choice.why;

  if (!initialise_display(choice.display, error)) return nullptr;
  std::unique_ptr<EglContext> ctx(new EglContext);
  ctx->display_ = choice.display;

  const char* display_ext = eglQueryString(ctx->display_, EGL_EXTENSIONS);
  if (!has_extension(display_ext, "EGL_KHR_surfaceless_context")) {
    *error = "the EGL display cannot make a context current without a surface (no EGL_KHR_surfaceless_context)";
    return nullptr;
  }
  if (!eglBindAPI(EGL_OPENGL_API)) {
    *error = egl_failure("eglBindAPI(EGL_OPENGL_API)") + ": the EGL implementation offers no desktop OpenGL";
    return nullptr;
  }
  EGLConfig config = nullptr;
  const bool no_config = has_extension(display_ext, "EGL_KHR_no_config_context");
  if (!no_config) {
    const EGLint attrs[] = {EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT, EGL_NONE};
    EGLint n = 0;
    if (!eglChooseConfig(ctx->display_, attrs, &config, 1, &n) || n < 1) {
      *error = "no EGL config renders OpenGL";
      return nullptr;
    }
  }
  // 4.2 is the least this renderer needs (instanced draws with a base
  // instance); newer is asked for first.
  static constexpr int kVersions[][2] = {{4, 6}, {4, 5}, {4, 3}, {4, 2}};
  for (const auto& v : kVersions) {
    const EGLint attrs[] = {EGL_CONTEXT_MAJOR_VERSION, v[0], EGL_CONTEXT_MINOR_VERSION, v[1],
                            EGL_CONTEXT_OPENGL_PROFILE_MASK, EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT, EGL_NONE};
    ctx->context_ = eglCreateContext(ctx->display_, no_config ? EGL_NO_CONFIG_KHR : config, EGL_NO_CONTEXT, attrs);
    if (ctx->context_ != EGL_NO_CONTEXT) break;
  }
  if (ctx->context_ == EGL_NO_CONTEXT) {
    *error = egl_failure("eglCreateContext") + ": no OpenGL 4.2 (or newer) core context";
    return nullptr;
  }
  if (!ctx->make_current(error)) return nullptr;
  const auto* renderer = reinterpret_cast<const char*>(glGetString(GL_RENDERER));
  const auto* version = reinterpret_cast<const char*>(glGetString(GL_VERSION));
  info->gl_renderer = renderer ? renderer : "?";
  info->gl_version = version ? version : "?";
  return ctx;
}

EglContext::~EglContext() {
  if (display_ == EGL_NO_DISPLAY) return;
  if (context_ != EGL_NO_CONTEXT) {
    if (eglGetCurrentContext() == context_) eglMakeCurrent(display_, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
    eglDestroyContext(display_, context_);
  }
}

bool EglContext::make_current(std::string* error) {
  // The bound API is per thread.
  if (eglQueryAPI() != EGL_OPENGL_API && !eglBindAPI(EGL_OPENGL_API)) {
    *error = egl_failure("eglBindAPI(EGL_OPENGL_API)");
    return false;
  }
  if (eglGetCurrentContext() == context_) return true;
  if (!eglMakeCurrent(display_, EGL_NO_SURFACE, EGL_NO_SURFACE, context_)) {
    *error = egl_failure("eglMakeCurrent");
    return false;
  }
  return true;
}

}  // namespace voxvis::render::detail
