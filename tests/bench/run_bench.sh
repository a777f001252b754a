#!/usr/bin/env bash
# Builds Release and runs the frame benchmarks, writing JSON to build/bench.json.
#
#   tests/bench/run_bench.sh                       # all benchmarks, 5 repetitions
#   REPS=3 tests/bench/run_bench.sh --benchmark_filter=hidden_dynamic
#
# Extra arguments go to bench_frame (Google Benchmark flags). Environment:
#   BUILD_DIR  build directory (default: <repo>/build)
#   REPS       --benchmark_repetitions (default 5)
# Afterwards it prints, when both ran, the hidden_dynamic ratios
# median_us(n:100000) / median_us(n:1000), point and region frames, in
# the first 10 s and at steady state (the goal is <= 1.20), and, when
# it ran, the walkthrough's resolution ratio 200x120x200 / 100x60x100
# (walkthrough/resolution: ratio_of_least; the goal is <= 1.5).
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
BUILD_DIR="${BUILD_DIR:-$ROOT/build}"
REPS="${REPS:-5}"
OUT="$BUILD_DIR/bench.json"

generator=()
if command -v ninja >/dev/null 2>&1 && [ ! -f "$BUILD_DIR/CMakeCache.txt" ]; then
  generator=(-G Ninja)
fi
cmake -S "$ROOT" -B "$BUILD_DIR" "${generator[@]}" -DCMAKE_BUILD_TYPE=Release \
  -DVOXVIS_BUILD_BENCHMARKS=ON -DVOXVIS_SANITIZE=OFF >/dev/null
cmake --build "$BUILD_DIR" --target bench_frame

"$BUILD_DIR/bench_frame" \
  --benchmark_repetitions="$REPS" \
  --benchmark_report_aggregates_only=true \
  --benchmark_out="$OUT" \
  --benchmark_out_format=json \
  "$@"

echo "wrote $OUT"

if command -v python3 >/dev/null 2>&1; then
  python3 - "$OUT" <<'EOF'
import json, re, sys
data = json.load(open(sys.argv[1]))
med = {}
res = {}
for b in data.get("benchmarks", []):
    # With repetitions, use the median aggregate; without, the single run.
    if b.get("run_type") == "aggregate" and b.get("aggregate_name") != "median":
        continue
    name = re.sub(r"/iterations:\d+", "", b.get("run_name", b["name"]))
    if "median_us" in b:
        med[name] = b["median_us"]
    if "ratio_of_least" in b:
        res[name] = b
for pre, sfx in (("", ""), ("", "/ob:256"), ("/region", "/ob:256"), ("/steady", "/ob:256"),
                 ("/steady/region", "/ob:256")):
    lo = med.get("hidden_dynamic" + pre + "/n:1000" + sfx)
    hi = med.get("hidden_dynamic" + pre + "/n:100000" + sfx)
    if lo and hi:
        ratio = hi / lo
        verdict = "OK" if ratio <= 1.2 else "ABOVE the 1.20 goal"
        print(f"hidden_dynamic{pre}{sfx}: median_us n:1000 = {lo:.1f}, n:100000 = {hi:.1f}, ratio {ratio:.2f} ({verdict})")
for name, b in res.items():
    r = b["ratio_of_least"]
    verdict = "OK" if r <= 1.5 else "ABOVE the 1.5 goal"
    print(f"{name}: least-time medians {b['coarse_least_us']:.0f} / {b['fine_least_us']:.0f} us, "
          f"ratio {r:.2f} ({verdict}); per-step ratio {b['ratio_median']:.2f}, of medians {b['ratio_of_medians']:.2f}")
EOF
fi
