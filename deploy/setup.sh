#!/usr/bin/env bash
# Set-up command 1: installs what is missing (Debian 12), builds voxvis in
# build/, and runs the main job: `voxvis replay` of the bundled walkthrough
# of the paper-like scene, with a per-run summary.
set -euo pipefail
cd "$(dirname "$0")/.."
source deploy/deps.sh
voxvis_ensure_deps

cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release
cmake --build build

echo "voxvis: replaying examples/paper (5,000 spheres, 200 moving, 300 frames)" >&2
build/voxvis replay --scene examples/paper/scene.json --frames examples/paper/frames.jsonl \
  --out build/paper-pvs.jsonl
echo "voxvis: per-frame answers written to build/paper-pvs.jsonl" >&2
