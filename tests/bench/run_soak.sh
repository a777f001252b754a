#!/usr/bin/env bash
# Soak (figures in docs/server.md, "Soak: a hostile mix beside a well-behaved
# viewer"): the Soak test of test_server (tests/server/soak.h) run for longer
# on a Release build. One voxvis-server on loopback; one viewer at 30 Hz on a
# lattice of 5,000 spheres, whose answer gaps are measured, beside a hostile
# mix (bad times and ids, GetPvs floods, dropped View streams, bad and too
# fast moves, create/delete races, malformed bytes, extreme cameras, huge
# creates, stream bursts, well-behaved and hostile Tick streams); the
# server's RSS is sampled every 100 ms. Then the same viewer alone, as a
# baseline.
#
#   tests/bench/run_soak.sh                          # 120 s + 120 s baseline
#   SOAK_SECONDS=600 tests/bench/run_soak.sh
#   VOXVIS_SOAK_MIX=floods,races tests/bench/run_soak.sh   # only those loops
#   BASELINE=0 tests/bench/run_soak.sh               # no baseline run
#
# Environment: BUILD_DIR (default <repo>/build), SOAK_SECONDS (default 120),
# BASELINE (default 1), VOXVIS_SOAK_MIX (default every loop). The output of
# each run goes to $BUILD_DIR/soak/*.txt.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
BUILD_DIR="${BUILD_DIR:-$ROOT/build}"
SOAK_SECONDS="${SOAK_SECONDS:-120}"
BASELINE="${BASELINE:-1}"
OUT="$BUILD_DIR/soak"

cmake -S "$ROOT" -B "$BUILD_DIR" -DCMAKE_BUILD_TYPE=Release -DVOXVIS_SANITIZE=OFF >/dev/null
cmake --build "$BUILD_DIR" --target test_server voxvis-server

rm -rf "$OUT"
mkdir -p "$OUT"
echo "== machine: $(nproc) cores, load average $(cut -d' ' -f1-3 /proc/loadavg)"

run() {  # name gtest-filter: runs one test, keeps its output, prints its figures
  local status=0
  VOXVIS_SOAK_SECONDS="$SOAK_SECONDS" "$BUILD_DIR/test_server" --gtest_filter="$2" \
    --gtest_also_run_disabled_tests >"$OUT/$1.txt" 2>&1 || status=$?
  sed -n '/^soak: /,/^server answering/p' "$OUT/$1.txt"
  grep -E '^\[  (FAILED|PASSED) ' "$OUT/$1.txt" || true
  return "$status"
}

echo "== Hostile mix beside one viewer at 30 Hz, $SOAK_SECONDS s"
status=0
run mix 'Soak.HostileMixBesideAWellBehavedViewer' || status=$?
if [ "$BASELINE" != 0 ]; then
  echo "== The same viewer alone, $SOAK_SECONDS s"
  run baseline 'Soak.DISABLED_ViewerAloneBaseline' || status=$?
fi
echo "== load average after: $(cut -d' ' -f1-3 /proc/loadavg)"
exit "$status"
