#!/usr/bin/env bash
# Server benchmarks over loopback (figures in docs/performance.md, "Server"):
#   1. round trip of one viewer at 60 Hz on the paper-like scene at
#      100x60x100 (examples/paper), and on a light scene (200 spheres, grid
#      25x15x25) whose engine time is tiny, so its round trip is the cost of
#      the server and the transport;
#   2. viewers at 60 Hz on one paper-like scene, and split over two copies of
#      it (frames of one scene run one at a time; two scenes use both cores):
#      the most viewers with p99 <= 10 ms is the figure asked for;
#   3. viewers at 60 Hz on the light scene: the server's own capacity when
#      frames cost little.
#
#   tests/bench/run_server_bench.sh              # all, about 4 minutes
#   DURATION=5 tests/bench/run_server_bench.sh   # shorter runs
#   VIEWERS="1 2 3 4" tests/bench/run_server_bench.sh
#
# Environment: BUILD_DIR (default <repo>/build), DURATION seconds per run
# (default 15), VIEWERS the counts to try (default "1 2 3 4 6 8 12 16"),
# LIGHT_VIEWERS those for the light scene (default "1 16 64 128 256").
# Reports go to $BUILD_DIR/server-bench/*.json (voxvis loadgen --json).
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
BUILD_DIR="${BUILD_DIR:-$ROOT/build}"
DURATION="${DURATION:-15}"
VIEWERS="${VIEWERS:-1 2 3 4 6 8 12 16}"
LIGHT_VIEWERS="${LIGHT_VIEWERS:-1 16 64 128 256}"
OUT="$BUILD_DIR/server-bench"

cmake -S "$ROOT" -B "$BUILD_DIR" -DCMAKE_BUILD_TYPE=Release -DVOXVIS_SANITIZE=OFF >/dev/null
cmake --build "$BUILD_DIR" --target voxvis-server voxvis

rm -rf "$OUT"
mkdir -p "$OUT"
"$BUILD_DIR/voxvis" generate --preset paper --objects 200 --dynamic 20 --frames 300 \
  --scene-out "$OUT/light-auto.json" --frames-out "$OUT/light-frames.jsonl"
sed -e 's/^  "bounds": \(.*\),$/  "bounds": \1, "grid": [25, 15, 25],/' "$OUT/light-auto.json" >"$OUT/light.json"

"$BUILD_DIR/voxvis-server" --listen 127.0.0.1:0 --port-file "$OUT/port" --data-dir "$OUT/data" \
  --scene "paper=$ROOT/examples/paper/scene.json" --scene "paper2=$ROOT/examples/paper/scene.json" \
  --scene "light=$OUT/light.json" \
  2>"$OUT/server.log" &
server=$!
trap 'kill -TERM $server 2>/dev/null; wait $server 2>/dev/null || true' EXIT
for _ in $(seq 1 300); do [ -s "$OUT/port" ] && break; sleep 0.1; done
[ -s "$OUT/port" ] || { echo "server did not start:"; cat "$OUT/server.log"; exit 1; }
addr="127.0.0.1:$(cat "$OUT/port")"

report() {  # name...: one line per loadgen report
  python3 - "$OUT" "$@" <<'PY'
import json, sys
out = sys.argv[1]
for name in sys.argv[2:]:
    d = json.load(open(f"{out}/{name}.json"))
    print(f"{name:14s} viewers {d['viewers']:3d}  fps {d['fps']:7.1f} (asked {d['viewers'] * d['rate_hz']:6.0f})"
          f"  p50 {d['p50_ms']:6.2f} ms  p99 {d['p99_ms']:6.2f} ms  max {d['max_ms']:6.2f} ms"
          f"  skipped by server {d['server_skipped']}  errors {d['errors'] or 'none'}")
PY
}

load() {  # name scene frames viewers
  "$BUILD_DIR/voxvis" loadgen --server "$addr" --scene "$2" --frames "$3" --viewers "$4" \
    --rate 60 --duration "$DURATION" --json "$OUT/$1.json" -q >/dev/null
}

paper_frames="$ROOT/examples/paper/frames.jsonl"
echo "== One viewer at 60 Hz: round trip"
load one-paper paper "$paper_frames" 1 && report one-paper
load one-light light "$OUT/light-frames.jsonl" 1 && report one-light

echo "== Viewers at 60 Hz on one paper-like scene (100x60x100)"
for n in $VIEWERS; do
  load "one-scene-$n" paper "$paper_frames" "$n" && report "one-scene-$n"
done

echo "== Viewers at 60 Hz split over two copies of the scene"
for n in $VIEWERS; do
  [ "$n" -ge 2 ] || continue
  half=$((n / 2))
  load "two-scenes-$n-a" paper "$paper_frames" "$half" &
  first=$!
  load "two-scenes-$n-b" paper2 "$paper_frames" "$((n - half))"
  wait "$first"
  report "two-scenes-$n-a" "two-scenes-$n-b"
done

echo "== Viewers at 60 Hz on the light scene (200 spheres, 25x15x25)"
for n in $LIGHT_VIEWERS; do
  load "light-$n" light "$OUT/light-frames.jsonl" "$n" && report "light-$n"
done
