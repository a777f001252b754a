#!/usr/bin/env bash
# Server benchmarks over loopback (figures in docs/performance.md, "Server"):
#   1. round trip of one viewer at 60 Hz on the paper-like scene at
#      100x60x100 (examples/paper), and on a light scene (transport cost);
#   2. the most viewers at 60 Hz on the paper-like scene with p99 <= 10 ms.
#
#   tests/bench/run_server_bench.sh              # all, about 4 minutes
#   DURATION=5 tests/bench/run_server_bench.sh   # shorter runs
#   VIEWERS="1 2 3 4" tests/bench/run_server_bench.sh
#
# Environment: BUILD_DIR (default <repo>/build), DURATION seconds per run
# (default 15), VIEWERS the counts to try (default "1 2 3 4 6 8 12 16").
# Reports go to $BUILD_DIR/server-bench/*.json (voxvis loadgen --json).
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
BUILD_DIR="${BUILD_DIR:-$ROOT/build}"
DURATION="${DURATION:-15}"
VIEWERS="${VIEWERS:-1 2 3 4 6 8 12 16}"
OUT="$BUILD_DIR/server-bench"

cmake -S "$ROOT" -B "$BUILD_DIR" -DCMAKE_BUILD_TYPE=Release -DVOXVIS_SANITIZE=OFF >/dev/null
cmake --build "$BUILD_DIR" --target voxvis-server voxvis

rm -rf "$OUT"
mkdir -p "$OUT"
"$BUILD_DIR/voxvis" generate --preset paper --objects 200 --dynamic 20 --frames 300 \
  --scene-out "$OUT/light.json" --frames-out "$OUT/light-frames.jsonl"

"$BUILD_DIR/voxvis-server" --listen 127.0.0.1:0 --port-file "$OUT/port" --data-dir "$OUT/data" \
  --scene "paper=$ROOT/examples/paper/scene.json" --scene "light=$OUT/light.json" \
  2>"$OUT/server.log" &
server=$!
trap 'kill -TERM $server 2>/dev/null; wait $server 2>/dev/null || true' EXIT
for _ in $(seq 1 300); do [ -s "$OUT/port" ] && break; sleep 0.1; done
[ -s "$OUT/port" ] || { echo "server did not start:"; cat "$OUT/server.log"; exit 1; }
addr="127.0.0.1:$(cat "$OUT/port")"

run() {  # name scene frames viewers
  "$BUILD_DIR/voxvis" loadgen --server "$addr" --scene "$2" --frames "$3" --viewers "$4" \
    --rate 60 --duration "$DURATION" --json "$OUT/$1.json" 2>/dev/null >/dev/null
  printf '%-14s viewers %3s  ' "$1" "$4"
  sed -e 's/[{}"]//g' -e 's/,/  /g' "$OUT/$1.json"
  echo
}

echo "== One viewer at 60 Hz: round trip"
run one-paper paper "$ROOT/examples/paper/frames.jsonl" 1
run one-light light "$OUT/light-frames.jsonl" 1

echo "== Viewers at 60 Hz on the paper-like scene (100x60x100)"
for n in $VIEWERS; do
  run "paper-$n" paper "$ROOT/examples/paper/frames.jsonl" "$n"
done
