// generate_cmd.cpp — `voxvis generate`: writes a scene file and a frames file
// from a preset (generate.h).
#include <string>

#include "cli.h"
#include "output_file.h"
#include "voxvis/format.h"
#include "voxvis/generate.h"

namespace voxvis::cli {

int run_generate(const GenerateArgs& args) {
  if (args.preset != "paper") {
    return report(FormatError{"", 0, "--preset", "unknown preset '" + args.preset + "' (known: paper)"});
  }
  if (args.objects < 0) {
    return report(FormatError{"", 0, "--objects", "must be >= 0, got " + std::to_string(args.objects)});
  }
  if (args.dynamic < 0 || args.dynamic > args.objects) {
    return report(FormatError{"", 0, "--dynamic",
                              "must be in [0, --objects = " + std::to_string(args.objects) +
                                  "], got " + std::to_string(args.dynamic)});
  }
  if (args.frames < 0) {
    return report(FormatError{"", 0, "--frames", "must be >= 0, got " + std::to_string(args.frames)});
  }

  PaperSceneParams scene_params;
  scene_params.objects = args.objects;
  scene_params.dynamic = args.dynamic;
  scene_params.seed = args.seed;
  const SceneDesc scene = make_paper_scene(scene_params);

  WalkthroughParams walk_params;
  walk_params.frames = args.frames;
  walk_params.seed = args.seed + 1;  // Defaults: scene seed 1, walkthrough seed 2.
  const std::vector<FrameInput> frames = make_walkthrough(scene, walk_params);

  // Each file is written whole or not at all (temporary file, then rename).
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

}  // namespace voxvis::cli
