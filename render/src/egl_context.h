// egl_context.h — an OpenGL core context with no window system: display
// selection (device platform, surfaceless fallback), context creation, and
// teardown that leaves other contexts on the same display alone.
#pragma once

#include <memory>
#include <string>

#include <EGL/egl.h>

#include "voxvis/render.h"

namespace voxvis::render::detail {

class EglContext {
 public:
  /// Null on failure, with `error` naming the step and what is missing.
  static std::unique_ptr<EglContext> create(const ContextOptions& options, ContextInfo* info,
                                            std::string* error);
  ~EglContext();
  EglContext(const EglContext&) = delete;
  EglContext& operator=(const EglContext&) = delete;

  /// Binds the OpenGL API and makes the context current on the calling thread.
  bool make_current(std::string* error);

 private:
  EglContext() = default;
  EGLDisplay display_ = EGL_NO_DISPLAY;
  EGLContext context_ = EGL_NO_CONTEXT;
};

}  // namespace voxvis::render::detail
