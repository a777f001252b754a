// render_check.h — a renderer for the render tests, or why this machine
// cannot make one (no EGL vendor, no device or surfaceless platform, no
// OpenGL 4.2 core context): the tests then skip, naming it, so that they
// fail only on a wrong answer. CI's llvmpipe makes one.
#pragma once

#include <memory>
#include <string>

#include <gtest/gtest.h>

#include "voxvis/render.h"

namespace voxvis::test {

inline std::unique_ptr<render::Renderer> try_renderer(render::Platform platform, std::string* why) {
  render::ContextOptions o;
  o.platform = platform;
  return render::Renderer::create(o, why);
}

}  // namespace voxvis::test

/// Declares `var`, a renderer on `platform`; skips the test, saying why,
/// when the machine cannot make one.
#define VOXVIS_RENDERER_OR_SKIP(var, platform)                          \
  std::string var##_why;                                                \
  auto var = ::voxvis::test::try_renderer(platform, &var##_why);        \
  if (!var) GTEST_SKIP() << "no renderer on this machine: " << var##_why
