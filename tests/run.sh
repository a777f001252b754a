#!/usr/bin/env bash
# Set-up command 2: installs what is missing, then builds and runs the whole
# test suite twice: a Release build, and a build under AddressSanitizer and
# UndefinedBehaviorSanitizer; builds the container image and plays the
# Kubernetes manifests under podman. Also checks that the benchmarks run (their
# figures are not judged here; see docs/performance.md), and fuzzes the
# parsers for a few seconds per target (docs/fuzzing.md).
set -euo pipefail
cd "$(dirname "$0")/.."
source deploy/deps.sh
voxvis_ensure_deps tests

jobs=$(nproc 2>/dev/null || echo 2)

# Each stage's start says how long the run and the stage before took, and
# the run ends with the whole breakdown (where CI's time goes).
timings=()
stage_name="dependencies"
stage_start=$SECONDS
stage() {
  timings+=("$(printf '%6ds  %s' $((SECONDS - stage_start)) "$stage_name")")
  stage_name="$1"
  stage_start=$SECONDS
  echo "== $1 (at ${SECONDS}s)" >&2
}

# Longest tests first from the first run on: ctest schedules by the cost
# data of earlier runs in the build folder, and a fresh one has none, so the
# long tests start where they are declared, some last, with a core idle at
# the end. tests/ctest-costs.txt holds the 60 longest of a Release run
# (seconds; ctest's own format); ctest refines the copy as it runs.
seed_test_costs() {
  local f="$1/Testing/Temporary/CTestCostData.txt"
  [ -f "$f" ] || { mkdir -p "$(dirname "$f")" && cp tests/ctest-costs.txt "$f"; }
}

stage "Release build and tests"
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release
cmake --build build -j "$jobs"
seed_test_costs build
ctest --test-dir build --output-on-failure -j "$jobs"

# The container image built and served, and the Kubernetes manifests podman
# plays (tests/deploy/container_test.sh; it says SKIPPED, with the reason,
# where podman cannot run). The image is built around this Release build's
# binaries (deploy/image.sh --binaries build); its build stage, compiling
# voxvis as deploy/image.sh ships it (about 9 minutes more), runs when that
# stage's inputs changed since it last passed (the test says so).
stage "Container image and manifests"
bash tests/deploy/container_test.sh

stage "Benchmarks run (one short pass, figures not judged)"
build/bench_frame --benchmark_filter='hidden_dynamic/n:1000/' >/dev/null

stage "AddressSanitizer + UndefinedBehaviorSanitizer build and tests"
# -O1 -g1 (AddressSanitizer's own advice, with line tables in every report):
# half the compile time of RelWithDebInfo's -O2 -g under the sanitizers (a
# test file: 113 s -> 53 s), which on a fresh 2-core machine is most of CI's.
cmake -S . -B build-asan -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DVOXVIS_SANITIZE=ON \
  -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1 -DNDEBUG" -DVOXVIS_BUILD_BENCHMARKS=OFF
cmake --build build-asan -j "$jobs"
# The sanitizer build also checks the engine's invariants (VOXVIS_ASSERT,
# voxvis/assert.h; compiled out of Release).
# Under the sanitizers every test runs, the property and hard-case tests at a
# quarter of their count (VOXVIS_TEST_SCALE, tests/support/scenes.h): they
# check that the same code paths touch memory and arithmetic soundly, which a
# quarter of the random scenes and rays exercises; the Release stage above
# runs the full counts for the statistics.
# intercept_tls_get_addr=0: the leak checker's tracking of dynamic TLS (the
# TLS of dlopen'd libraries: Mesa's EGL driver) guesses glibc's TLS layout from
# an address's alignment, and on glibc 2.36 the guess can go wrong with the
# heap's layout and crash its tracer at exit ("Tracer caught signal 11", the
# process exits 1 after a clean run; google/sanitizers#1322). Leaks are still
# checked everywhere else.
seed_test_costs build-asan
VOXVIS_TEST_SCALE="${VOXVIS_TEST_SCALE:-0.25}" \
  ASAN_OPTIONS=detect_leaks=1:abort_on_error=1:intercept_tls_get_addr=0 \
  UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
  ctest --test-dir build-asan --output-on-failure -j "$jobs"

# A short pass (VOXVIS_FUZZ_SECONDS per target): the clang build of the engine
# library and the targets, then every target in turn; any crash, hang, leak
# or sanitizer report fails the run. tests/fuzz/run_fuzz.sh runs them longer.
stage "Fuzz targets of the parsers (clang, libFuzzer + ASan + UBSan)"
bash tests/fuzz/run_fuzz.sh "${VOXVIS_FUZZ_SECONDS:-10}"
stage "done"
printf '%s\n' "== Time per stage (seconds):" "${timings[@]}" >&2
