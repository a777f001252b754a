// options.h — what the subcommands' registrations share (options.cpp): the
// option groups several commands take (server, region, EGL, --tbv-period)
// and the checks those make after parsing.
#pragma once

#include <functional>
#include <memory>
#include <string>

#include "cli.h"

namespace CLI {
class App;
class Option;
}  // namespace CLI

namespace voxvis::cli {

/// The options of every command that talks to voxvis-server; with `fleet`,
/// --servers too (the commands that name a scene, and those that visit every
/// server).
void add_net_options(CLI::App* cmd, NetArgs* net, bool fleet = true);

/// The region flags (replay, verify, view, tick, loadgen): set on every
/// frame's camera, over the frames file's fields.
void add_region_options(CLI::App* cmd, RegionArgs* region);

/// The headless renderer's options (verify, report).
void add_egl_options(CLI::App* cmd, EglArgs* egl);

/// --tbv-period as parsed (replay, verify, export): the value is checked
/// after parsing, by take().
struct TbvPeriodOption {
  CLI::Option* option = nullptr;
  double value = -1.0;
  /// When given: 0 (adaptive) or a finite number of seconds >= kMinTbvPeriod,
  /// set on `engine`. A bad value is reported and take() returns false (the
  /// command exits with kExitError).
  bool take(EngineArgs* engine) const;
};

/// Adds --tbv-period to `cmd` with `help`; keep the result until the command
/// runs (the option writes into it).
std::shared_ptr<TbvPeriodOption> add_tbv_period_option(CLI::App* cmd, const std::string& help);

/// Runs a command that names a scene (delete, view, tick, simulate, loadgen):
/// with a fleet (--servers), `net` first points at the scene's owner
/// (route_scene); a bad list is reported and its exit status returned
/// without running `run`.
int run_routed(NetArgs* net, const std::string& scene, const std::function<int()>& run);

}  // namespace voxvis::cli
