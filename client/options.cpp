// options.cpp — the option groups several subcommands take, and the checks
// those make after parsing (options.h).
#include "options.h"

#include <cmath>

#include <CLI/CLI.hpp>

#include "voxvis/format.h"

namespace voxvis::cli {

void add_net_options(CLI::App* cmd, NetArgs* net, bool fleet) {
  CLI::Option* server = cmd->add_option("--server", net->server, "Server address")
                            ->capture_default_str()
                            ->type_name("HOST:PORT");
  if (fleet) {
    cmd->add_option("--servers", net->servers,
                    "A fleet instead of one server: each scene goes to its owner by rendezvous hashing "
                    "over the shards' names (an entry without NAME= is named by its host's first DNS "
                    "label, a StatefulSet pod's name, or by HOST:PORT for an IP address; "
                    "docs/deploy.md)")
        ->type_name("[NAME=]HOST:PORT,...")
        ->excludes(server);
  }
  cmd->add_option("--token-file", net->token_file,
                  "File holding the bearer token (first non-comment line); default "
                  "$VOXVIS_TOKEN_FILE, else no token. Never pass tokens on the command line.")
      ->type_name("FILE");
  cmd->add_option("--tls-ca", net->tls_ca, "PEM root certificates; enables TLS")
      ->type_name("FILE");
  cmd->add_option("--tls-server-name", net->tls_server_name,
                  "Name to check the server's certificate against (default: the host of --server)")
      ->type_name("NAME");
}

void add_region_options(CLI::App* cmd, RegionArgs* region) {
  cmd->add_option("--eye-extent", region->eye_extent,
                  "Every frame's answer holds for every eye of the box eye +- H (world units, each in "
                  "[0, 1e12]; H alone: the same on all three axes)")
      ->type_name("H|HX,HY,HZ");
  cmd->add_flag("--omnidirectional", region->omnidirectional,
                "Every frame's answer holds in every direction (near and far still bound distance)");
  cmd->add_option_function<double>(
         "--horizon", [region](const double& s) { region->horizon = s; },
         "Every frame's answer holds until this many seconds after its time, each moving object anywhere "
         "its max_speed reaches (in [0, 1e9])")
      ->type_name("SECONDS");
}

void add_egl_options(CLI::App* cmd, EglArgs* egl) {
  cmd->add_option("--egl-platform", egl->platform, "EGL platform: auto, device or surfaceless")
      ->type_name("NAME")
      ->capture_default_str();
  cmd->add_option("--egl-device", egl->device,
                  "EGL device index as eglQueryDevicesEXT lists them (device platform); default: the first "
                  "GPU, else the software one")
      ->type_name("N");
  cmd->add_option("--id-readback", egl->id_readback,
                  "How the id pass's visible set comes back: set (a compute pass gathers the ids seen, only "
                  "those are read), image (the whole id image), auto (set on a GPU, image on a software "
                  "renderer)")
      ->type_name("auto|set|image")
      ->capture_default_str();
  cmd->add_option("--query-readback", egl->query_readback,
                  "How occlusion queries' results come back: batch (a round at once through a query buffer, "
                  "OpenGL 4.4), each (one read per query)")
      ->type_name("batch|each")
      ->capture_default_str();
}

bool TbvPeriodOption::take(EngineArgs* engine) const {
  if (option->count() == 0) return true;
  if (!std::isfinite(value) || !(value == 0.0 || value >= kMinTbvPeriod)) {
    report(FormatError{"", 0, "--tbv-period",
                       "must be 0 (adaptive) or a finite number of seconds >= " + number_text(kMinTbvPeriod)});
    return false;
  }
  engine->tbv_period = value;
  return true;
}

std::shared_ptr<TbvPeriodOption> add_tbv_period_option(CLI::App* cmd, const std::string& help) {
  auto tbv = std::make_shared<TbvPeriodOption>();
  tbv->option = cmd->add_option("--tbv-period", tbv->value, help)->type_name("SECONDS");
  return tbv;
}

int run_routed(NetArgs* net, const std::string& scene, const std::function<int()>& run) {
  int exit_code = kExitOk;
  if (!route_scene(net, scene, &exit_code)) return exit_code;
  return run();
}

}  // namespace voxvis::cli
