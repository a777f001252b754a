#!/usr/bin/env bash
# Tick benchmarks over loopback (figures in docs/performance.md, "Ticks"),
# the targets of the Tick stream on a 2-core machine, `voxvis-server` and
# `voxvis loadgen --tick` on the same machine:
#   1. the server's own CPU per answer on a light scene (200 spheres, grid
#      25x15x25), the engine's CPU subtracted: <= 50 us (the View stream's
#      figure beside it, for comparison);
#   2. 24 viewers at 128 Hz on the indoor level (voxvis generate --preset
#      indoor): every tick answered, tick latency p99 <= 4 ms;
#   3. 64 viewers at 30 Hz on the bundled walkthrough (examples/paper):
#      every tick answered, p99 <= 33 ms;
#   4. one scene, ticks sent faster than answered (latest tick wins): answers
#      a second with 4 viewers a tick >= 1.8x those with 1, on the static city
#      (voxvis generate --preset city) and on the walkthrough (dynamic).
#
#   tests/bench/run_tick_bench.sh               # all, about 2 minutes (DURATION 10)
#   DURATION=5 tests/bench/run_tick_bench.sh    # shorter runs
#
# Environment: BUILD_DIR (default <repo>/build), DURATION seconds per run
# (default 10). Reports go to $BUILD_DIR/tick-bench/*.json (loadgen --json).
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
BUILD_DIR="${BUILD_DIR:-$ROOT/build}"
DURATION="${DURATION:-10}"
OUT="$BUILD_DIR/tick-bench"

cmake -S "$ROOT" -B "$BUILD_DIR" -DCMAKE_BUILD_TYPE=Release -DVOXVIS_SANITIZE=OFF >/dev/null
cmake --build "$BUILD_DIR" --target voxvis-server voxvis

rm -rf "$OUT"
mkdir -p "$OUT"
voxvis="$BUILD_DIR/voxvis"
"$voxvis" generate --preset paper --objects 200 --dynamic 20 --frames 300 \
  --scene-out "$OUT/light-auto.json" --frames-out "$OUT/light-frames.jsonl" >/dev/null
sed -e 's/^  "bounds": \(.*\),$/  "bounds": \1, "grid": [25, 15, 25],/' "$OUT/light-auto.json" >"$OUT/light.json"
"$voxvis" generate --preset indoor --scene-out "$OUT/indoor.json" --frames-out "$OUT/indoor-frames.jsonl" >/dev/null
"$voxvis" generate --preset city --scene-out "$OUT/city.json" --frames-out "$OUT/city-frames.jsonl" >/dev/null
paper_frames="$ROOT/examples/paper/frames.jsonl"

"$BUILD_DIR/voxvis-server" --listen 127.0.0.1:0 --port-file "$OUT/port" --data-dir "$OUT/data" \
  --metrics 127.0.0.1:0 --scene "light=$OUT/light.json" --scene "indoor=$OUT/indoor.json" \
  --scene "paper=$ROOT/examples/paper/scene.json" --scene "city=$OUT/city.json" 2>"$OUT/server.log" &
server=$!
trap 'kill -TERM $server 2>/dev/null; wait $server 2>/dev/null || true' EXIT
for _ in $(seq 1 300); do [ -s "$OUT/port" ] && break; sleep 0.1; done
[ -s "$OUT/port" ] || { echo "server did not start:"; cat "$OUT/server.log"; exit 1; }
addr="127.0.0.1:$(cat "$OUT/port")"
metrics="$(sed -n 's|.*metrics at http://\([^/]*\)/metrics.*|\1|p' "$OUT/server.log" | head -1)"
[ -n "$metrics" ] || { echo "no metrics address in the server's log:"; cat "$OUT/server.log"; exit 1; }

load() {  # name scene frames viewers rate [loadgen options...]
  local name=$1 scene=$2 frames=$3 viewers=$4 rate=$5
  shift 5
  "$voxvis" loadgen --server "$addr" --metrics "$metrics" --scene "$scene" --frames "$frames" \
    --viewers "$viewers" --rate "$rate" --duration "$DURATION" --json "$OUT/$name.json" -q "$@" >/dev/null
}

load light-tick light "$OUT/light-frames.jsonl" 64 60 --tick
load light-view light "$OUT/light-frames.jsonl" 64 60
load indoor-24 indoor "$OUT/indoor-frames.jsonl" 24 128 --tick
load paper-64 paper "$paper_frames" 64 30 --tick
load city-sat-1 city "$OUT/city-frames.jsonl" 1 2000 --tick
load city-sat-4 city "$OUT/city-frames.jsonl" 4 2000 --tick
load paper-sat-1 paper "$paper_frames" 1 2000 --tick
load paper-sat-4 paper "$paper_frames" 4 2000 --tick

python3 - "$OUT" <<'PY'
import json, sys
out = sys.argv[1]
r = {n: json.load(open(f"{out}/{n}.json")) for n in
     ["light-tick", "light-view", "indoor-24", "paper-64", "city-sat-1", "city-sat-4", "paper-sat-1",
      "paper-sat-4"]}

def line(name):
    d = r[name]
    ticks = (f"ticks {d['ticks_answered']}/{d['ticks_sent']} (server skipped {d['server_skipped']}, "
             f"send skipped {d['send_skipped']})  " if d["mode"] == "tick" else "")
    cpu = (f"  server CPU {1e6 * d['server_cpu_s_per_answer']:.1f} us/answer, engine "
           f"{1e6 * d['server_engine_s_per_answer']:.1f}, own {1e6 * d['server_overhead_s_per_answer']:.1f}"
           if "server_cpu_s_per_answer" in d else "")
    print(f"{name:12s} {d['mode']:4s} viewers {d['viewers']:3d} at {d['rate_hz']:g} Hz  {ticks}"
          f"answers/s {d['answers_per_s']:8.1f}  p50 {d['p50_ms']:6.2f}  p99 {d['p99_ms']:6.2f}  "
          f"max {d['max_ms']:6.2f} ms{cpu}  errors {d['errors'] or 'none'}")

for n in r:
    line(n)

def all_answered(d):  # Every tick sent was answered (the client's own late sends are shown above).
    return d["ticks_answered"] == d["ticks_sent"] and not d["errors"]

own = 1e6 * r["light-tick"]["server_overhead_s_per_answer"]
def ratio(scene):
    return r[f"{scene}-sat-4"]["answers_per_s"] / max(r[f"{scene}-sat-1"]["answers_per_s"], 1e-9)
targets = [
    ("server's own CPU per answer, light scene", f"{own:.1f} us (<= 50)", own <= 50),
    ("24 viewers at 128 Hz, indoor", f"all answered {all_answered(r['indoor-24'])}, p99 "
     f"{r['indoor-24']['p99_ms']:.2f} ms (<= 4)", all_answered(r["indoor-24"]) and r["indoor-24"]["p99_ms"] <= 4),
    ("64 viewers at 30 Hz, walkthrough", f"all answered {all_answered(r['paper-64'])}, p99 "
     f"{r['paper-64']['p99_ms']:.2f} ms (<= 33)", all_answered(r["paper-64"]) and r["paper-64"]["p99_ms"] <= 33),
    ("4 viewers a tick vs 1, answers/s, city (static)", f"{ratio('city'):.2f}x (>= 1.8)", ratio("city") >= 1.8),
    ("4 viewers a tick vs 1, answers/s, walkthrough (dynamic)", f"{ratio('paper'):.2f}x (>= 1.8)",
     ratio("paper") >= 1.8),
]
print()
for name, value, ok in targets:
    print(f"{'met   ' if ok else 'missed'} {name}: {value}")
PY
