// generate_cmd.cpp — `voxvis generate`: writes a scene file and a frames file
// from a preset (generate.h).
#include <charconv>
#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <string_view>
#include <system_error>
#include <vector>

#include <CLI/CLI.hpp>

#include "cli.h"
#include "output_file.h"
#include "voxvis/format.h"
#include "voxvis/generate.h"

namespace voxvis::cli {
namespace {

enum class Kind { Paper, Indoor, VoxelWorld, VoxelCave, City, Arena };

/// A preset and the meaning, default and range of its --size.
struct Preset {
  const char* name;
  Kind kind;
  std::uint64_t default_seed;  ///< The benchmark's seed (tests/bench/bench_frame.cpp); 1 for paper.
  int default_x, default_z;    ///< --size default (z only for indoor).
  int min_size, max_size;      ///< Per axis.
  const char* size_unit;       ///< What --size counts.
  const char* cap_reason;      ///< Why max_size.
};

// The caps keep scenes to at most about half a million objects (scene files
// below 40 MB) and grids of at most 34 million voxels (the engine accepts
// 2^27), which `voxvis replay` runs in well under a gigabyte.
constexpr Preset kPresets[] = {
    {"paper", Kind::Paper, 1, 0, 0, 0, 0, "", ""},
    {"indoor", Kind::Indoor, 7, 6, 3, 1, 100, "rooms per side",
     "100 x 100 rooms are about 100,000 objects"},
    {"voxel-world", Kind::VoxelWorld, 11, 64, 0, 16, 256, "columns per side",
     "256 x 256 columns are about 500,000 blocks"},
    {"voxel-cave", Kind::VoxelCave, 11, 64, 0, 16, 256, "columns per side",
     "256 x 256 columns are about 500,000 blocks"},
    {"city", Kind::City, 5, 8, 0, 1, 64, "blocks per side",
     "64 x 64 blocks are a grid of 1028 x 32 x 1028, 34 million voxels"},
    {"arena", Kind::Arena, 3, 4, 0, 2, 32, "rooms per side",
     "32 x 32 rooms are a grid of 1025 x 26 x 1304, 35 million voxels"},
};

/// The arena's players: a match's 24 by default; 1,000 keeps a frames file
/// of 100,000 frames under 10 GB.
constexpr int kArenaPlayers = 24, kMaxArenaPlayers = 1000;

/// Frames: 100,000 at 60 per second is almost half an hour.
constexpr int kMaxFrames = 100000;

const Preset* find_preset(const std::string& name) {
  for (const Preset& p : kPresets) {
    if (name == p.name) return &p;
  }
  return nullptr;
}

std::string known_presets() {
  std::string out;
  for (const Preset& p : kPresets) {
    if (!out.empty()) out += ", ";
    out += p.name;
  }
  return out;
}

/// A decimal integer with an optional sign; values beyond int64 saturate (so
/// that they fail the range check with the text quoted). False when `text`
/// is not a number.
bool parse_integer(std::string_view text, std::int64_t* out) {
  bool negative = false;
  if (!text.empty() && (text.front() == '+' || text.front() == '-')) {
    negative = text.front() == '-';
    text.remove_prefix(1);
  }
  if (text.empty()) return false;
  for (const char c : text) {
    if (c < '0' || c > '9') return false;
  }
  std::uint64_t v = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
  if (end != text.data() + text.size()) return false;
  constexpr std::uint64_t kMax = static_cast<std::uint64_t>(std::numeric_limits<std::int64_t>::max());
  if (ec == std::errc::result_out_of_range || v > kMax) v = kMax;
  *out = negative ? -static_cast<std::int64_t>(v) : static_cast<std::int64_t>(v);
  return true;
}

/// A seed: decimal digits only (no sign, no base prefix), at most 2^64 - 1.
bool parse_seed(std::string_view text, std::uint64_t* out) {
  if (text.empty()) return false;
  for (const char c : text) {
    if (c < '0' || c > '9') return false;
  }
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), *out);
  return ec == std::errc() && end == text.data() + text.size();
}

/// Parses --size for a non-paper preset: "N", or for indoor also "XxZ" (N
/// alone: N x N rooms). On error sets `message`.
bool parse_size(const std::string& text, const Preset& preset, int* x, int* z, std::string* message) {
  const bool two = preset.kind == Kind::Indoor;
  std::string expect = preset.size_unit;
  expect += " of preset '";
  expect += preset.name;
  expect += two ? "' must be N or XxZ (e.g. 6x3) with integers in [" : "' must be an integer in [";
  expect += std::to_string(preset.min_size) + ", " + std::to_string(preset.max_size) + "]";
  const std::string got = ", got '" + text + "'";

  std::string_view first = text, second;
  if (const std::size_t sep = text.find_first_of("xX"); sep != std::string::npos) {
    if (!two) {
      *message = expect + " (one number: the scene is square)" + got;
      return false;
    }
    first = std::string_view(text).substr(0, sep);
    second = std::string_view(text).substr(sep + 1);
  }
  std::int64_t a = 0, b = 0;
  if (!parse_integer(first, &a) || (!second.empty() && !parse_integer(second, &b)) ||
      (second.empty() && first.size() != text.size())) {
    *message = expect + got;
    return false;
  }
  if (second.empty()) b = a;
  for (const std::int64_t v : {a, b}) {
    if (v < preset.min_size || v > preset.max_size) {
      *message = expect + got;
      if (v > preset.max_size) {
        *message += " (";
        *message += preset.cap_reason;
        *message += ")";
      }
      return false;
    }
  }
  *x = static_cast<int>(a);
  *z = static_cast<int>(b);
  return true;
}

/// Writes both files, each whole or not at all (temporary file, then rename).
int write_files(const GenerateArgs& args, const SceneDesc& scene, const std::vector<FrameInput>& frames) {
  OutputFile scene_out;
  OutputFile frames_out;
  std::string message;
  if (!scene_out.open(args.scene_out, &message)) return report(FormatError{args.scene_out, 0, "", message});
  if (!frames_out.open(args.frames_out, &message)) {
    return report(FormatError{args.frames_out, 0, "", message});
  }
  bool ok = scene_out.write(scene_to_json(scene));
  std::string line;
  for (const FrameInput& f : frames) {
    line = frame_to_json(f);
    line += '\n';
    ok = ok && frames_out.write(line);
  }
  if (!ok) return report(FormatError{"", 0, "", "cannot write the output files"});
  if (!scene_out.commit(&message)) return report(FormatError{args.scene_out, 0, "", message});
  if (!frames_out.commit(&message)) return report(FormatError{args.frames_out, 0, "", message});
  return kExitOk;
}

}  // namespace

int run_generate(const GenerateArgs& args) {
  const Preset* preset = find_preset(args.preset);
  if (preset == nullptr) {
    return report(FormatError{"", 0, "--preset",
                              "unknown preset '" + args.preset + "' (known: " + known_presets() + ")"});
  }
  if (args.frames < 0 || args.frames > kMaxFrames) {
    return report(FormatError{"", 0, "--frames",
                              "must be in [0, " + std::to_string(kMaxFrames) +
                                  "] (28 minutes at 60 per second), got " + std::to_string(args.frames)});
  }
  std::uint64_t seed = preset->default_seed;
  if (args.seed && !parse_seed(*args.seed, &seed)) {
    return report(FormatError{"", 0, "--seed",
                              "must be an integer in [0, 18446744073709551615], got '" + *args.seed + "'"});
  }

  if (preset->kind == Kind::Paper) {
    if (args.size) {
      return report(FormatError{"", 0, "--size",
                                "does not apply to preset 'paper' (its scene is sized by --objects)"});
    }
    const int objects = args.objects.value_or(PaperSceneParams{}.objects);
    const int dynamic = args.dynamic.value_or(PaperSceneParams{}.dynamic);
    if (objects < 0) {
      return report(FormatError{"", 0, "--objects", "must be >= 0, got " + std::to_string(objects)});
    }
    if (dynamic < 0 || dynamic > objects) {
      return report(FormatError{"", 0, "--dynamic",
                                "must be in [0, --objects = " + std::to_string(objects) + "], got " +
                                    std::to_string(dynamic)});
    }
    PaperSceneParams scene_params;
    scene_params.objects = objects;
    scene_params.dynamic = dynamic;
    scene_params.seed = seed;
    const SceneDesc scene = make_paper_scene(scene_params);

    WalkthroughParams walk_params;
    walk_params.frames = args.frames;
    walk_params.seed = seed + 1;  // Defaults: scene seed 1, walkthrough seed 2.
    return write_files(args, scene, make_walkthrough(scene, walk_params));
  }

  // The other presets are sized by --size; only the arena has movers, its
  // players (--dynamic).
  const auto not_here = [&](const char* flag, const char* presets) {
    std::string message = "applies to ";
    message += presets;
    message += " only, not to '";
    message += preset->name;
    message += preset->kind == Kind::Arena ? "' (its players are --dynamic; it is sized by --size)"
                                           : "' (a static scene, sized by --size)";
    return report(FormatError{"", 0, flag, message});
  };
  if (args.objects) return not_here("--objects", "preset 'paper'");
  if (args.dynamic && preset->kind != Kind::Arena) return not_here("--dynamic", "presets 'paper' and 'arena'");
  int x = preset->default_x, z = preset->default_z;
  if (args.size) {
    std::string message;
    if (!parse_size(*args.size, *preset, &x, &z, &message)) return report(FormatError{"", 0, "--size", message});
  }
  if (preset->kind == Kind::Arena) {
    const int players = args.dynamic.value_or(kArenaPlayers);
    if (players < 0 || players > kMaxArenaPlayers) {
      return report(FormatError{"", 0, "--dynamic",
                                "the arena's players: must be in [0, " + std::to_string(kMaxArenaPlayers) +
                                    "], got " + std::to_string(players)});
    }
    const ArenaLevel arena = make_arena(x, players, args.frames, seed);
    return write_files(args, arena.scene, arena.frames);
  }
  ScenePath path;
  switch (preset->kind) {
    case Kind::Indoor: path = make_indoor_level(x, z, args.frames, seed); break;
    case Kind::VoxelWorld: path = make_voxel_world(x, args.frames, false, seed); break;
    case Kind::VoxelCave: path = make_voxel_world(x, args.frames, true, seed); break;
    case Kind::City: path = make_city(x, args.frames, seed); break;
    case Kind::Paper:
    case Kind::Arena: break;  // Handled above.
  }
  return write_files(args, path.scene, camera_frames(path.cameras));
}

Command add_generate_command(CLI::App& app) {
  auto args = std::make_shared<GenerateArgs>();
  GenerateArgs* gen = args.get();
  CLI::App* cmd = app.add_subcommand("generate", "Write a deterministic example scene and camera walkthrough.");
  cmd->add_option("--preset", gen->preset,
                  "Scene preset: paper (clusters of spheres, some moving, as in Batagelo & Wu), "
                  "indoor (rooms, walls and doorways), voxel-world (terrain of unit blocks, path "
                  "over the surface), voxel-cave (the same world, path through a cave), city "
                  "(box buildings and parked cars, path along a street), arena (a Quake-3-sized level "
                  "of rooms, corridors and two storeys with 24 players running through it, a "
                  "first-person walk)")
      ->type_name("NAME")
      ->capture_default_str();
  cmd->add_option("--scene-out", gen->scene_out, "Scene file to write")->required()->type_name("FILE");
  cmd->add_option("--frames-out", gen->frames_out, "Frames file to write")->required()->type_name("FILE");
  cmd->add_option_function<std::string>(
         "--size", [gen](const std::string& text) { gen->size = text; },
         "Not paper: indoor, rooms per side, N or XxZ (1..100, default 6x3); voxel-world "
         "and voxel-cave, columns per side (16..256, default 64); city, blocks per side "
         "(1..64, default 8); arena, rooms per side (2..32, default 4)")
      ->type_name("N|XxZ");
  cmd->add_option_function<int>(
         "--objects", [gen](const int& n) { gen->objects = n; }, "paper: number of spheres (default 5000)")
      ->type_name("N");
  cmd->add_option_function<int>(
         "--dynamic", [gen](const int& n) { gen->dynamic = n; },
         "paper: how many of them move (default 200); arena: players (0..1000, default 24)")
      ->type_name("N");
  cmd->add_option("--frames", gen->frames, "Number of frames (60 per second), 0..100000")
      ->type_name("N")
      ->capture_default_str();
  cmd->add_option_function<std::string>(
         "--seed", [gen](const std::string& text) { gen->seed = text; },
         "Random seed of the scene (default 1 for paper; for the others the benchmarks' seed: "
         "indoor 7, voxel-world and voxel-cave 11, city 5, arena 3); paper's walkthrough uses seed + 1")
      ->type_name("N");
  cmd->footer(
      "The same arguments always produce byte-identical files. Only paper and arena\n"
      "have moving objects; the other presets are static and their frames carry no moves.\n"
      "Examples:\n"
      "  voxvis generate --preset paper --scene-out paper.json --frames-out paper.jsonl\n"
      "  voxvis generate --preset indoor --size 4x2 --scene-out indoor.json --frames-out indoor.jsonl\n"
      "  voxvis generate --preset voxel-cave --frames 600 --scene-out cave.json --frames-out cave.jsonl\n"
      "  voxvis generate --preset city --size 4 --seed 9 --scene-out city.json --frames-out city.jsonl\n"
      "  voxvis generate --preset arena --frames 600 --scene-out arena.json --frames-out arena.jsonl");
  return {cmd, [args] { return run_generate(*args); }};
}

}  // namespace voxvis::cli
