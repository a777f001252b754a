#!/usr/bin/env bash
# Set-up command 1: installs what is missing (Debian 12), builds voxvis in
# build/, and runs the main job (deploy/demo.sh): voxvis-server on the bundled
# paper-like scene, a client walkthrough against it over the socket with a
# per-frame summary, and a graceful stop of the server.
set -euo pipefail
cd "$(dirname "$0")/.."
source deploy/deps.sh
voxvis_ensure_deps

cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release
cmake --build build

exec bash deploy/demo.sh
