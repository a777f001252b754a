#!/usr/bin/env bash
# run_import_bench.sh [TRIANGLES] — a static level from a model file to its
# first frame (docs/performance.md, "Importing a mesh level"): writes a
# rolling terrain of about TRIANGLES triangles (default 1,000,000) as an OBJ
# file over 256 x 64 x 256 world units, then times
#   1. voxvis import  terrain.obj -> terrain.json (assimp's reading, the node
#      walk, the triangles' checks, the scene file written);
#   2. voxvis replay  terrain.json with one frame (the scene file read,
#      Scene::create, the first frame);
# each with its wall time, CPU time and peak resident memory
# (/usr/bin/time), and their sum. The grid is 256 x 64 x 256 voxels, as in
# bench_frame's mesh_build.
#
# Environment: BUILD_DIR (default <repo>/build; builds voxvis there when it
# is missing), WORK (default $BUILD_DIR/import-bench).
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
BUILD_DIR="${BUILD_DIR:-$ROOT/build}"
WORK="${WORK:-$BUILD_DIR/import-bench}"
triangles="${1:-1000000}"
if ! [[ "$triangles" =~ ^[1-9][0-9]*$ ]]; then
  echo "usage: tests/bench/run_import_bench.sh [TRIANGLES]   (a whole number >= 1, got '$triangles')" >&2
  exit 2
fi
if ! [ -x /usr/bin/time ]; then
  echo "run_import_bench: error: /usr/bin/time not found (Debian package 'time')" >&2
  exit 2
fi
if ! [ -x "$BUILD_DIR/voxvis" ]; then
  cmake -S "$ROOT" -B "$BUILD_DIR" -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
  cmake --build "$BUILD_DIR" --target voxvis
fi
cli="$BUILD_DIR/voxvis"
mkdir -p "$WORK"

# The terrain: (side + 1)^2 vertices, 2 side^2 triangles, height
# 20 + 8 sin(x / 17) cos(z / 23), as bench_frame's mesh_build.
side=$(awk -v n="$triangles" 'BEGIN { s = int(sqrt(n / 2)); if (s < 1) s = 1; print s }')
obj="$WORK/terrain-$triangles.obj"
if ! [ -f "$obj" ]; then
  awk -v s="$side" 'BEGIN {
    print "o Terrain"
    for (j = 0; j <= s; ++j)
      for (i = 0; i <= s; ++i) {
        x = 256.0 * i / s; z = 256.0 * j / s
        printf "v %.6f %.6f %.6f\n", x, 20.0 + 8.0 * sin(x / 17.0) * cos(z / 23.0), z
      }
    for (j = 0; j < s; ++j)
      for (i = 0; i < s; ++i) {
        v = j * (s + 1) + i + 1; w = v + s + 1
        printf "f %d %d %d\nf %d %d %d\n", v, v + 1, w, v + 1, w + 1, w
      }
  }' >"$obj.tmp"
  mv "$obj.tmp" "$obj"
fi
echo "run_import_bench: $obj: $((2 * side * side)) triangles, $(du -h "$obj" | cut -f1)" >&2

# One frame from above the terrain, looking across it.
frames="$WORK/frame.jsonl"
echo '{"t": 0, "eye": [10, 40, 10], "dir": [1, -0.3, 1], "up": [0, 1, 0], "fov_y_deg": 60, "aspect": 1.7778, "near": 0.05, "far": 1000}' >"$frames"

# step NAME COMMAND...: runs it under /usr/bin/time; prints and records
# wall seconds, CPU seconds and peak resident kB.
declare -A wall cpu rss
step() {
  local name="$1"
  shift
  /usr/bin/time -f '%e %U %S %M' -o "$WORK/$name.time" "$@"
  read -r w u s m <"$WORK/$name.time"
  wall[$name]=$w
  cpu[$name]=$(awk -v u="$u" -v s="$s" 'BEGIN { printf "%.2f", u + s }')
  rss[$name]=$m
  printf 'run_import_bench: %-7s wall %6.2f s, CPU %6.2f s, peak RSS %5d MB\n' "$name" "$w" "${cpu[$name]}" \
    $((m / 1024)) >&2
}

step import "$cli" import "$obj" --scene-out "$WORK/terrain.json" --grid 256,64,256 -q
echo "run_import_bench: terrain.json: $(du -h "$WORK/terrain.json" | cut -f1)" >&2
step replay "$cli" replay --scene "$WORK/terrain.json" --frames "$frames" --out "$WORK/pvs.jsonl" -q

awk -v wi="${wall[import]}" -v wr="${wall[replay]}" -v ci="${cpu[import]}" -v cr="${cpu[replay]}" \
    -v mi="${rss[import]}" -v mr="${rss[replay]}" 'BEGIN {
  printf "run_import_bench: file to first frame: wall %.2f s, CPU %.2f s; peak RSS %d MB (import), %d MB (replay)\n",
         wi + wr, ci + cr, mi / 1024, mr / 1024 > "/dev/stderr"
}'
