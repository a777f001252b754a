// egl_select.h — which EGL platform and device the renderer takes, decided
// from what the EGL library says of itself: pure functions over its
// extension strings, so that the choice is tested with the strings of every
// vendor (Mesa's, NVIDIA's; tests/render/test_egl_select.cpp) on any machine.
//
// The device platform needs EGL_EXT_platform_device and a way to list
// devices: EGL_EXT_device_enumeration by name, or EGL_EXT_device_base,
// which the EGL registry defines as EGL_EXT_device_enumeration and
// EGL_EXT_device_query together. Mesa lists all three; NVIDIA's driver
// (through glvnd) lists only EGL_EXT_device_base.
#pragma once

#include <string>
#include <vector>

namespace voxvis::render::detail {

/// Whether the space-separated extension list holds `name` exactly.
bool has_extension(const char* list, const char* name);

/// Whether the client extensions offer the device platform; when not,
/// `why_not` names what is missing.
bool device_platform_offered(const char* client_extensions, std::string* why_not);

/// Whether the client extensions offer Mesa's surfaceless platform; when
/// not, `why_not` says so.
bool surfaceless_offered(const char* client_extensions, std::string* why_not);

/// The device the renderer takes.
struct DevicePick {
  int index = -1;       ///< As eglQueryDevicesEXT lists the devices.
  bool software = false;  ///< Mesa's software renderer (EGL_MESA_device_software).
  std::string why;      ///< "the first of 2 devices that is not a software renderer", ...
};

/// Chooses among the devices eglQueryDevicesEXT lists (`devices`: each one's
/// extension string, in its order). `wanted` >= 0 (--egl-device N) is taken
/// as it is; -1 takes the first device that is not a software renderer
/// (a GPU: NVIDIA's, Mesa's hardware drivers), else the software one. False,
/// with `error` saying why, for no device or a `wanted` beyond the list.
bool choose_device(const std::vector<std::string>& devices, int wanted, DevicePick* out, std::string* error);

}  // namespace voxvis::render::detail
