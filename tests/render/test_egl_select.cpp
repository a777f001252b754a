// The choice of EGL platform and device (render/src/egl_select.h) over the
// exact extension strings of the vendors voxvis runs on: Mesa 22.3 here
// (llvmpipe, no GPU), and NVIDIA's driver 580.159 through glvnd on an H200
// (docs/verify.md, "On an NVIDIA GPU"). Before, the device platform needed
// EGL_EXT_device_enumeration by name, which NVIDIA does not list: voxvis
// fell back to the surfaceless platform there, and --egl-device could not
// pick a GPU.
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "egl_select.h"

namespace voxvis::render::detail {
namespace {

// eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS) and each device's
// eglQueryDeviceStringEXT(EGL_EXTENSIONS), as printed.
const char* const kMesaClient =
    "EGL_EXT_device_base EGL_EXT_device_enumeration EGL_EXT_device_query EGL_EXT_platform_base "
    "EGL_KHR_client_get_all_proc_addresses EGL_EXT_client_extensions EGL_KHR_debug EGL_EXT_platform_device "
    "EGL_EXT_platform_wayland EGL_KHR_platform_wayland EGL_EXT_platform_x11 EGL_KHR_platform_x11 "
    "EGL_EXT_platform_xcb EGL_MESA_platform_gbm EGL_KHR_platform_gbm EGL_MESA_platform_surfaceless";
const char* const kMesaSoftwareDevice = "EGL_MESA_device_software EGL_EXT_device_drm_render_node";
const char* const kNvidiaClient =
    "EGL_EXT_platform_base EGL_EXT_device_base EGL_KHR_client_get_all_proc_addresses EGL_EXT_client_extensions "
    "EGL_KHR_debug EGL_KHR_platform_x11 EGL_EXT_platform_x11 EGL_EXT_platform_device EGL_MESA_platform_surfaceless "
    "EGL_EXT_explicit_device";
const char* const kNvidiaDevice =
    "EGL_NV_device_cuda EGL_EXT_device_drm EGL_EXT_device_drm_render_node EGL_EXT_device_query_name "
    "EGL_EXT_device_persistent_id";

TEST(EglSelect, BothVendorsOfferTheDevicePlatform) {
  std::string why;
  EXPECT_TRUE(device_platform_offered(kMesaClient, &why)) << why;
  EXPECT_TRUE(device_platform_offered(kNvidiaClient, &why)) << "EGL_EXT_device_base stands for enumeration: " << why;
  EXPECT_TRUE(surfaceless_offered(kMesaClient, &why));
  EXPECT_TRUE(surfaceless_offered(kNvidiaClient, &why));
}

TEST(EglSelect, WithoutEnumerationOrThePlatformItSaysWhatIsMissing) {
  std::string why;
  EXPECT_FALSE(device_platform_offered("EGL_EXT_platform_base EGL_EXT_platform_device", &why));
  EXPECT_EQ(why, "the EGL device platform is not available (no EGL_EXT_device_base or EGL_EXT_device_enumeration "
                 "among the client extensions)");
  EXPECT_FALSE(device_platform_offered("EGL_EXT_device_base", &why));
  EXPECT_EQ(why, "the EGL device platform is not available (no EGL_EXT_platform_device among the client extensions)");
  EXPECT_FALSE(device_platform_offered(nullptr, &why));
  // Names are matched whole: a longer name is not the one asked for.
  EXPECT_FALSE(device_platform_offered("EGL_EXT_platform_device_x EGL_EXT_device_base_y", &why));
  EXPECT_FALSE(surfaceless_offered("EGL_MESA_platform_surfaceless2", &why));
}

TEST(EglSelect, AGpuIsPreferredToTheSoftwareRenderer) {
  DevicePick pick;
  std::string error;
  // Mesa alone: its software device.
  ASSERT_TRUE(choose_device({kMesaSoftwareDevice}, -1, &pick, &error)) << error;
  EXPECT_EQ(pick.index, 0);
  EXPECT_TRUE(pick.software);
  EXPECT_EQ(pick.why, "the only device, a software renderer");
  // NVIDIA alone: its GPU.
  ASSERT_TRUE(choose_device({kNvidiaDevice}, -1, &pick, &error)) << error;
  EXPECT_EQ(pick.index, 0);
  EXPECT_FALSE(pick.software);
  // Both vendors installed (glvnd lists every vendor's devices): the GPU,
  // wherever it is listed.
  ASSERT_TRUE(choose_device({kMesaSoftwareDevice, kNvidiaDevice, kNvidiaDevice}, -1, &pick, &error)) << error;
  EXPECT_EQ(pick.index, 1);
  EXPECT_FALSE(pick.software);
  EXPECT_EQ(pick.why, "the first of 3 devices that is not a software renderer");
}

TEST(EglSelect, EglDeviceNamesDevicesAsTheyAreListed) {
  DevicePick pick;
  std::string error;
  const std::vector<std::string> four = {kNvidiaDevice, kNvidiaDevice, kMesaSoftwareDevice, kNvidiaDevice};
  for (int i = 0; i < 4; ++i) {
    ASSERT_TRUE(choose_device(four, i, &pick, &error)) << error;
    EXPECT_EQ(pick.index, i);
    EXPECT_EQ(pick.software, i == 2);
    EXPECT_EQ(pick.why, "--egl-device " + std::to_string(i) + " of 4 devices");
  }
  EXPECT_FALSE(choose_device(four, 4, &pick, &error));
  EXPECT_EQ(error, "--egl-device 4 does not exist: 4 EGL devices found (0 to 3)");
  EXPECT_FALSE(choose_device({}, -1, &pick, &error));
  EXPECT_EQ(error, "no EGL device found");
}

}  // namespace
}  // namespace voxvis::render::detail
