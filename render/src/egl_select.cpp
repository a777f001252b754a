// egl_select.cpp — see egl_select.h.
#include "egl_select.h"

#include <cstring>

namespace voxvis::render::detail {

bool has_extension(const char* list, const char* name) {
  if (list == nullptr) return false;
  const std::size_t n = std::strlen(name);
  for (const char* p = list; (p = std::strstr(p, name)) != nullptr; p += n) {
    const bool starts = p == list || p[-1] == ' ';
    const bool ends = p[n] == '\0' || p[n] == ' ';
    if (starts && ends) return true;
  }
  return false;
}

bool device_platform_offered(const char* client, std::string* why_not) {
  const bool platform = has_extension(client, "EGL_EXT_platform_device");
  const bool enumeration =
      has_extension(client, "EGL_EXT_device_base") || has_extension(client, "EGL_EXT_device_enumeration");
  if (platform && enumeration) return true;
  std::string missing;
  if (!platform) missing = "EGL_EXT_platform_device";
  if (!enumeration) missing += std::string(missing.empty() ? "" : " and ") + "EGL_EXT_device_base or EGL_EXT_device_enumeration";
  *why_not = "the EGL device platform is not available (no " + missing + " among the client extensions)";
  return false;
}

bool surfaceless_offered(const char* client, std::string* why_not) {
  if (has_extension(client, "EGL_MESA_platform_surfaceless")) return true;
  *why_not = "the surfaceless platform is not available (no EGL_MESA_platform_surfaceless among the client extensions)";
  return false;
}

bool choose_device(const std::vector<std::string>& devices, int wanted, DevicePick* out, std::string* error) {
  const int count = static_cast<int>(devices.size());
  const auto software = [&](int i) {
    return has_extension(devices[static_cast<std::size_t>(i)].c_str(), "EGL_MESA_device_software");
  };
  const std::string of = " of " + std::to_string(count) + (count == 1 ? " device" : " devices");
  if (count == 0) {
    *error = "no EGL device found";
    return false;
  }
  if (wanted >= count) {
    *error = "--egl-device " + std::to_string(wanted) + " does not exist: " + std::to_string(count) +
             " EGL device" + (count == 1 ? "" : "s") + " found (0 to " + std::to_string(count - 1) + ")";
    return false;
  }
  if (wanted >= 0) {
    *out = DevicePick{wanted, software(wanted), "--egl-device " + std::to_string(wanted) + of};
    return true;
  }
  for (int i = 0; i < count; ++i)
    if (!software(i)) {
      *out = DevicePick{i, false, "the first" + of + " that is not a software renderer"};
      return true;
    }
  *out = DevicePick{0, software(0), count == 1 ? "the only device, a software renderer"
                                               : "the first" + of + ", all software renderers"};
  return true;
}

}  // namespace voxvis::render::detail
