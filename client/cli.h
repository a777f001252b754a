// cli.h — the `voxvis` subcommands. Each returns the process exit status and
// reports its own errors on stderr as "voxvis: error: <file>:<line>: <field>: <message>";
// the networked ones (load, scenes, delete, view, simulate, loadgen) report a
// server's answer as "voxvis: error: server: <CODE>: <message>".
// Each subcommand adds itself to the app (add_<name>_command, in the file of
// its run_ function); main.cpp adds them in order and runs the one parsed.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "voxvis/format.h"
#include "voxvis/scene.h"

namespace CLI {
class App;
}  // namespace CLI

namespace voxvis::cli {

/// Exit statuses (docs/formats.md, "Exit status").
inline constexpr int kExitOk = 0;
inline constexpr int kExitInternal = 1;  ///< A bug or resource exhaustion.
inline constexpr int kExitError = 2;     ///< Bad input, bad arguments, I/O failure.

/// Prints "voxvis: error: <error.str()>" on stderr and returns kExitError.
int report(const FormatError& error);

/// A subcommand added to the app: `run` is called when it was the one parsed,
/// and returns the exit status. Its arguments live as long as `run`.
struct Command {
  CLI::App* app = nullptr;
  std::function<int()> run;
};

/// The subcommands, in the order `voxvis --help` lists them; each adds its
/// options to `app` (the files are those of their run_ functions).
Command add_replay_command(CLI::App& app);        // replay.cpp
Command add_verify_command(CLI::App& app);        // verify_cmd.cpp
Command add_verify_merge_command(CLI::App& app);  // verify_merge_cmd.cpp
Command add_export_command(CLI::App& app);        // export_cmd.cpp
Command add_report_command(CLI::App& app);        // report_cmd.cpp
Command add_generate_command(CLI::App& app);      // generate_cmd.cpp
Command add_import_command(CLI::App& app);        // import_cmd.cpp
Command add_load_command(CLI::App& app);          // load_cmd.cpp
Command add_scenes_command(CLI::App& app);        // load_cmd.cpp
Command add_delete_command(CLI::App& app);        // load_cmd.cpp
Command add_rebalance_command(CLI::App& app);     // fleet_cmd.cpp
Command add_health_command(CLI::App& app);        // health_cmd.cpp
Command add_view_command(CLI::App& app);          // view_cmd.cpp
Command add_tick_command(CLI::App& app);          // tick_cmd.cpp
Command add_simulate_command(CLI::App& app);      // simulate_cmd.cpp
Command add_loadgen_command(CLI::App& app);       // loadgen_cmd.cpp

/// The scene and engine options of the commands that run the engine
/// (`replay`, `verify`, `export`).
struct EngineArgs {
  std::string scene;  ///< voxvis-scene/1 file.
  std::string grid;   ///< "NX,NY,NZ" overriding the scene's grid; empty: keep.
  std::optional<double> tbv_period;  ///< Seconds; empty: engine default.
  int occlusion_buffer = 160;        ///< Occlusion buffer width, pixels; 0: off.
};

/// Reads and parses the scene file and applies the options (--grid,
/// --tbv-period, --occlusion-buffer). On error reports it, sets `*exit_code`
/// and returns false. `text` keeps the file for build_scene's messages.
bool load_scene(const EngineArgs& args, std::string* text, SceneDesc* desc, SceneOptions* options,
                int* exit_code);

/// Builds the engine's scene; errors name the scene file's line where one
/// applies. Frees `text` on success.
bool build_scene(const EngineArgs& args, std::string* text, const SceneDesc& desc, const SceneOptions& options,
                 std::unique_ptr<Scene>* scene, int* exit_code);

/// --eye-extent, --omnidirectional, --horizon: a region for every frame,
/// over what the frames file says (docs/formats.md, "Regions").
struct RegionArgs {
  std::string eye_extent;         ///< "H" or "HX,HY,HZ", world units; empty: the file's.
  bool omnidirectional = false;   ///< Every frame omnidirectional.
  std::optional<double> horizon;  ///< Seconds; empty: the file's.
};

/// What RegionArgs set, parsed and checked.
struct RegionOverride {
  bool extent_set = false, horizon_set = false, omnidirectional = false;
  Vec3 extent{0.0};
  double horizon = 0.0;
  /// Sets the fields these flags name on `camera`.
  void apply(Camera* camera) const;
};

/// Parses the flags; false, with `error` naming the flag, on a bad value
/// (the engine's rules: each half extent in [0, 1e12], horizon in [0, 1e9]).
bool parse_region_args(const RegionArgs& args, RegionOverride* out, FormatError* error);

struct ReplayArgs {
  EngineArgs engine;
  RegionArgs region;
  std::string frames;  ///< Frames file, JSON Lines.
  std::string out;     ///< Output file; empty: stdout.
  bool quiet = false;
};

int run_replay(const ReplayArgs& args);

/// The headless renderer's flags, verify's and report's alike.
struct EglArgs {
  std::string platform = "auto";        ///< --egl-platform: auto | device | surfaceless.
  int device = -1;                      ///< --egl-device; -1: a GPU, else the software device.
  std::string id_readback = "auto";     ///< --id-readback: auto | set | image (render.h, IdReadback).
  std::string query_readback = "batch";  ///< --query-readback: batch | each (ContextOptions::batch_queries).
};

struct VerifyArgs {
  EngineArgs engine;
  std::string frames;      ///< Frames file, JSON Lines.
  std::string pvs;         ///< PVS lines to check (`voxvis replay` output); empty: run the engine.
  std::string out;         ///< Output file; empty: stdout.
  std::string resolution = "640x360";  ///< WxH.
  std::string reference = "auto";      ///< auto | egl | raycast: who finds the visible set.
  std::string method = "ids";          ///< ids | queries (EGL only).
  bool full = false;       ///< Queries: probe every object in the frustum, not only the PVS.
  std::int64_t first_frame = 0;
  std::int64_t frame_count = -1;  ///< -1: to the end.
  EglArgs egl;
  RegionArgs region;              ///< As for replay: set on every frame.
  int region_eyes = 8;            ///< Region frames: random eyes besides the centre and corners.
  /// Region frames: also checked against the objects where the next K
  /// frames (within the frame's horizon) put them.
  int horizon_frames = 0;
  bool quiet = false;
};

struct ReportArgs {
  std::string scene;     ///< voxvis-scene/1 file.
  std::string frames;    ///< Frames file, JSON Lines.
  std::string configs;   ///< Configurations file; empty: the default sweep.
  std::string out = "report";          ///< Output directory.
  std::string resolution = "640x360";  ///< The exact reference's and the levels' pixels.
  std::string reference = "auto";      ///< auto | egl | raycast: who finds the exact set.
  std::string cost_model;              ///< near-optimal's cost model file; empty: the cache directory's.
  std::int64_t frame_count = -1;       ///< The first N frames; -1: all.
  EglArgs egl;
  bool quiet = false;
};

int run_report(const ReportArgs& args);

/// Exit status of `verify` when some visible object was missing from a PVS.
inline constexpr int kExitMissed = 3;

int run_verify(const VerifyArgs& args);

struct VerifyMergeArgs {
  std::vector<std::string> slices;  ///< `verify` outputs of slices, any order.
  std::string out;                  ///< The joined output; empty: stdout.
  std::int64_t frames = -1;         ///< Frames the slices must cover exactly (0..N-1); -1: unchecked.
};

/// `voxvis verify-merge`: slices joined in frame order, checked to follow
/// one another without gap or overlap, summarised; kExitMissed when any
/// frame has a miss.
int run_verify_merge(const VerifyMergeArgs& args);

struct GenerateArgs {
  std::string preset = "paper";  ///< paper | indoor | voxel-world | voxel-cave | city.
  std::string scene_out;
  std::string frames_out;
  std::optional<int> objects;  ///< paper only; empty: 5000.
  std::optional<int> dynamic;  ///< paper only; empty: 200.
  std::optional<std::string> size;  ///< Not paper: "N", or "XxZ" for indoor; empty: the preset's default.
  int frames = 300;
  std::optional<std::string> seed;  ///< Decimal, as given; empty: the preset's default (1 for paper).
};

int run_generate(const GenerateArgs& args);

/// Options of every command that talks to voxvis-server.
struct NetArgs {
  std::string server = "127.0.0.1:50051";  ///< HOST:PORT.
  /// A fleet, "[NAME=]HOST:PORT,..." (voxvis/routing.h); empty: `server` alone.
  std::string servers;
  std::string token_file;       ///< Bearer token file; empty: $VOXVIS_TOKEN_FILE, else none.
  std::string tls_ca;           ///< PEM roots; non-empty enables TLS.
  std::string tls_server_name;  ///< Name checked against the server's certificate.
};

/// With a fleet (`net->servers`), points `net->server` at the owner of
/// `scene_id`. On error (a bad list) reports it, sets `*exit_code` and
/// returns false.
bool route_scene(NetArgs* net, const std::string& scene_id, int* exit_code);

struct RebalanceArgs {
  NetArgs net;           ///< servers: the fleet as it is now.
  /// Servers leaving the fleet, "[NAME=]HOST:PORT,...": every scene they
  /// hold moves to its owner in `net.servers`.
  std::string drain;
  bool dry_run = false;  ///< Print the moves only.
};

/// `voxvis rebalance`: every scene of the fleet to its owner.
int run_rebalance(const RebalanceArgs& args);

struct LoadArgs {
  NetArgs net;
  std::string scene;  ///< voxvis-scene/1 file.
  std::string id;     ///< Scene id; empty: the file's stem, sanitized.
};

int run_load(const LoadArgs& args);

/// Lists the server's scenes, one line each.
int run_scenes(const NetArgs& net);

int run_delete(const NetArgs& net, const std::string& id);

/// Exit status of `health` when the server does not answer SERVING (or not
/// at all within the timeout).
inline constexpr int kExitNotServing = 4;

struct HealthArgs {
  NetArgs net;                ///< Only the address and TLS options are used: no token is needed.
  std::string service;        ///< Health service name; "": the whole server.
  double timeout = 5.0;       ///< Seconds to wait for the connection and the answer.
};

/// Prints the server's health status (SERVING, NOT_SERVING, ...): exit 0 when
/// SERVING, kExitNotServing otherwise or without an answer in time.
int run_health(const HealthArgs& args);

struct ViewArgs {
  NetArgs net;
  RegionArgs region;
  std::string scene;   ///< Scene id on the server.
  std::string frames;  ///< Frames file, JSON Lines.
  std::string out;     ///< Output file; empty: stdout.
  bool delta = false;  ///< Ask for PVS_DELTA answers (reassembled: same output).
  int every = 0;  ///< Print a one-line summary of every Nth frame on stderr; 0: none.
  bool quiet = false;
};

int run_view(const ViewArgs& args);

struct TickArgs {
  NetArgs net;
  RegionArgs region;
  std::string scene;   ///< Scene id on the server.
  std::string frames;  ///< Frames file, JSON Lines.
  /// One viewer: the output file (empty: stdout); several: a directory for
  /// viewer-<k>.jsonl.
  std::string out;
  int viewers = 1;     ///< Viewers a tick, each walking the recording from its own start.
  bool delta = false;  ///< Ask for PVS_DELTA answers (reassembled: same output).
  bool quiet = false;
};

int run_tick(const TickArgs& args);

struct SimulateArgs {
  NetArgs net;
  std::string scene;
  std::string frames;
  double rate = 0.0;  ///< Batches per second; 0: as fast as acknowledgements come.
  bool quiet = false;
};

int run_simulate(const SimulateArgs& args);

struct LoadgenArgs {
  NetArgs net;
  RegionArgs region;
  std::string scene;
  int viewers = 1;          ///< Concurrent View streams, or viewers in each tick (--tick).
  double rate = 30.0;       ///< Frames per second per viewer, Hz (ticks per second with --tick).
  double duration = 10.0;   ///< Seconds of sending.
  std::string frames;       ///< Cameras to loop over; empty: an orbit in the scene's bounds.
  bool delta = false;
  std::string json;         ///< Report as JSON to this file; empty: none.
  int connections = 0;      ///< TCP connections; 0: one per 100 viewers.
  bool tick = false;        ///< One Tick stream carrying every viewer, instead of View streams.
  std::string metrics;      ///< The server's metrics address (HOST:PORT): its CPU per answer; empty: none.
  bool quiet = false;
};

int run_loadgen(const LoadgenArgs& args);

struct ExportArgs {
  EngineArgs engine;
  std::string frames;       ///< Frames file, JSON Lines; empty: the scene alone.
  std::int64_t frame = -1;  ///< With `frames`: the 0-based frame whose culling is written.
  bool frame_given = false;
  std::string vdb;          ///< The .vdb file to write.
  bool quiet = false;
};

/// `voxvis export`: the scene's voxels, and with a frame its culling, as
/// OpenVDB grids (docs/formats.md, "VDB export").
int run_export(const ExportArgs& args);

/// Parses "NX,NY,NZ" (integers in [1, max_per_axis]); on error sets `message`.
bool parse_grid_arg(const std::string& text, int max_per_axis, int out[3], std::string* message);

}  // namespace voxvis::cli
