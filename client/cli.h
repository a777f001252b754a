// cli.h — the `voxvis` subcommands. Each returns the process exit status and
// reports its own errors on stderr as "voxvis: error: <file>:<line>: <field>: <message>".
#pragma once

#include <cstdint>
#include <optional>
#include <string>

#include "voxvis/format.h"

namespace voxvis::cli {

/// Exit statuses (docs/formats.md, "Exit status").
inline constexpr int kExitOk = 0;
inline constexpr int kExitInternal = 1;  ///< A bug or resource exhaustion.
inline constexpr int kExitError = 2;     ///< Bad input, bad arguments, I/O failure.

/// Prints "voxvis: error: <error.str()>" on stderr and returns kExitError.
int report(const FormatError& error);

struct ReplayArgs {
  std::string scene;   ///< voxvis-scene/1 file.
  std::string frames;  ///< Frames file, JSON Lines.
  std::string grid;    ///< "NX,NY,NZ" overriding the scene's grid; empty: keep.
  std::string out;     ///< Output file; empty: stdout.
  std::optional<double> tbv_period;  ///< Seconds; empty: engine default.
  bool quiet = false;
};

int run_replay(const ReplayArgs& args);

struct GenerateArgs {
  std::string preset = "paper";
  std::string scene_out;
  std::string frames_out;
  int objects = 5000;
  int dynamic = 200;
  int frames = 300;
  std::uint64_t seed = 1;
};

int run_generate(const GenerateArgs& args);

/// Parses "NX,NY,NZ" (integers in [1, max_per_axis]); on error sets `message`.
bool parse_grid_arg(const std::string& text, int max_per_axis, int out[3], std::string* message);

}  // namespace voxvis::cli
