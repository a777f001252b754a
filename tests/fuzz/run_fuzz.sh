#!/usr/bin/env bash
# run_fuzz.sh [SECONDS_PER_TARGET] — builds the libFuzzer targets of
# tests/fuzz (clang, AddressSanitizer with leak detection, UBSan) in
# build-fuzz/ and runs each for SECONDS_PER_TARGET seconds (default 60), one
# after the other. Exits non-zero if any target found a crash, a hang (an
# input slower than FUZZ_TIMEOUT seconds), a leak, an out-of-memory or a
# sanitizer report, and prints where the reproducer is. docs/fuzzing.md says
# more; tests/run.sh runs it for a few seconds per target.
#
# Environment: FUZZ_BUILD_DIR (default build-fuzz), FUZZ_TIMEOUT (seconds
# per input, default 10), FUZZ_MAX_LEN (bytes per input, default 16384),
# VOXVIS_CLI (a voxvis binary whose `generate` presets seed the corpora,
# default build/voxvis when there is one).
#
# What it keeps, under $FUZZ_BUILD_DIR/fuzz/:
#   corpus/<target>/     inputs that reached new code, merged after every run
#                        into a smallest set with the same coverage
#   seeds/<target>/      the seeds of the last run (read only for libFuzzer)
#   artifacts/<target>/  reproducers: crash-*, leak-*, timeout-*, oom-*
#   logs/<target>.log    libFuzzer's output of the last run
#   history.tsv          one line per run: date, target, seconds, CPU seconds,
#                        executions, coverage, corpus size, result
set -euo pipefail
cd "$(dirname "$0")/../.."

# The targets, in the order they run: fuzz_<name> of tests/fuzz/CMakeLists.txt,
# seeded from tests/fuzz/seeds/<name>/ (and seed_<name> below, if defined),
# with the dictionary tests/fuzz/<name>.dict if there is one.
TARGETS=(
  scene
  frames
  import
)

seconds="${1:-60}"
if ! [[ "$seconds" =~ ^[1-9][0-9]*$ ]]; then
  echo "usage: tests/fuzz/run_fuzz.sh [SECONDS_PER_TARGET]   (a whole number of seconds >= 1, got '$seconds')" >&2
  exit 2
fi
build="${FUZZ_BUILD_DIR:-build-fuzz}"
timeout="${FUZZ_TIMEOUT:-10}"
max_len="${FUZZ_MAX_LEN:-16384}"
cli="${VOXVIS_CLI:-build/voxvis}"
work="$build/fuzz"

say() { echo "run_fuzz: $*" >&2; }

for tool in clang clang++ cmake ninja; do
  if ! command -v "$tool" >/dev/null; then
    say "error: $tool not found; deploy/deps.sh lists the Debian packages (clang, libclang-rt-14-dev)"
    exit 2
  fi
done

say "building the fuzz targets in $build (clang, ASan + UBSan)"
mkdir -p "$build"
if ! { CC=clang CXX=clang++ cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DVOXVIS_FUZZ=ON &&
       cmake --build "$build" -j "$(nproc 2>/dev/null || echo 2)" -- $(printf 'fuzz_%s ' "${TARGETS[@]}"); } \
     >"$build/fuzz-build.log" 2>&1; then
  cat "$build/fuzz-build.log" >&2
  say "error: the fuzz build failed (log above, also in $build/fuzz-build.log)"
  exit 2
fi

# ---------------------------------------------------------------------------
# Seeds.

# The first $2 objects of a scene file written by scene_to_json (one object
# per line), still a valid scene: small seeds mutate faster.
first_objects() {
  awk -v n="$2" '
    /^    \{/ { if (++k > n) next; obj = $0; sub(/,$/, "", obj)
                if (pending != "") print pending ","; pending = obj; next }
    /^  \]/   { if (pending != "") print pending; pending = ""; print; next }
    { print }' "$1"
}

# Writes a small scene and frames file for each `voxvis generate` preset
# into $1 (once: they depend only on the presets).
generated() {
  local dir="$1"
  [ -x "$cli" ] || return 0
  [ -f "$dir/done" ] && return 0
  mkdir -p "$dir"
  local preset args
  for preset in paper indoor city voxel-world arena; do
    case "$preset" in
      paper) args=(--objects 30 --dynamic 5) ;;
      indoor|city) args=(--size 1) ;;
      voxel-world) args=(--size 16) ;;
      arena) args=(--size 2 --dynamic 3) ;;
    esac
    "$cli" generate --preset "$preset" "${args[@]}" --frames 3 \
      --scene-out "$dir/$preset.json" --frames-out "$dir/$preset.jsonl" >/dev/null
  done
  touch "$dir/done"
}

seed_scene() {
  local out="$1" f
  first_objects examples/paper/scene.json 12 >"$out/example-paper.json"
  for f in "$work/generated"/*.json; do
    [ -f "$f" ] && first_objects "$f" 12 >"$out/generated-$(basename "$f")"
  done
  return 0
}

seed_frames() {
  local out="$1" f
  # Two lines of the walkthrough, with the first three of their 200 moves.
  head -n 2 examples/paper/frames.jsonl |
    sed -E 's/("moves": \[(\{[^}]*\}, ){2}\{[^}]*\})(, \{[^}]*\})*\]/\1]/' >"$out/example-paper.jsonl"
  for f in "$work/generated"/*.jsonl; do
    [ -f "$f" ] && cp "$f" "$out/generated-$(basename "$f")"
  done
  return 0
}

# Small models of Debian's assimp-testmodels (when installed), each behind
# the byte that chooses its format in fuzz_import.cpp.
seed_import() {
  local out="$1" dir="/usr/share/assimp/models" f ext byte
  [ -d "$dir" ] || return 0
  for f in "$dir"/glTF2/*/*.gltf "$dir"/glTF2/*/*.glb "$dir"/OBJ/*.obj "$dir"/PLY/*.ply "$dir"/STL/*.stl \
           "$dir"/OFF/*.off; do
    [ -f "$f" ] && [ "$(stat -c %s "$f")" -le "$max_len" ] || continue
    ext="${f##*.}"
    case "${ext,,}" in
      gltf) byte='\x00' ;; glb) byte='\x01' ;; obj) byte='\x02' ;; ply) byte='\x03' ;; stl) byte='\x04' ;;
      off) byte='\x05' ;; *) continue ;;
    esac
    { printf "$byte"; cat "$f"; } >"$out/testmodels-$(basename "$(dirname "$f")")-$(basename "$f")"
  done
  return 0
}

generated "$work/generated"

# ---------------------------------------------------------------------------
# Runs.

# Targets that run code not of this project on the fuzzed bytes (fuzz_import:
# Debian's assimp, not instrumented). They run in libFuzzer's fork mode,
# which goes on after a crash, hang or out-of-memory; each reproducer is then
# run again and its stack decides whose bug it is: the first frame in
# libassimp.so or in voxvis's code. assimp's are kept (renamed assimp-*) and
# listed in assimp-findings.tsv, not failures of the run: `voxvis import`
# reads models in a child process for them (docs/fuzzing.md, "Findings in assimp").
# Any other finding fails the run.
FORK_TARGETS=" import "

# owner_of BIN REPRODUCER: "assimp", "voxvis", "clean" (the input alone
# runs without a finding), or "unknown" (no stack names either). A timeout's
# input runs again with six times the limit: libFuzzer's limit is wall-clock
# time, so on a loaded machine an input of a second's work can pass it,
# while a hang still hangs and its stack then says whose it is.
owner_of() {
  local limit="$timeout"
  case "$(basename "$2")" in timeout-*) limit=$((timeout * 6)) ;; esac
  { timeout $((limit + 120)) "$1" -timeout="$limit" -rss_limit_mb=2048 -malloc_limit_mb=2048 "$2" 2>&1 || true; } |
    awk '/fuzz check failed/ { print "voxvis"; found = 1; exit }
         /^ *#[0-9]+ 0x/ {
           if ($0 ~ /libassimp\.so/) { print "assimp"; found = 1; exit }
           if ($0 ~ / in voxvis::|LLVMFuzzerTestOneInput/) { print "voxvis"; found = 1; exit }
         }
         /^==[0-9]+== ?ERROR|^SUMMARY/ { error = 1 }
         /^Executed .* in [0-9]+ ms/ { executed = 1 }
         END { if (!found) print (executed && !error ? "clean" : "unknown") }'
}

export ASAN_OPTIONS="detect_leaks=1${ASAN_OPTIONS:+:$ASAN_OPTIONS}"
# Leaks inside assimp on inputs it refuses are its own (tests/fuzz/lsan.supp).
export LSAN_OPTIONS="suppressions=$PWD/tests/fuzz/lsan.supp${LSAN_OPTIONS:+:$LSAN_OPTIONS}"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1${UBSAN_OPTIONS:+:$UBSAN_OPTIONS}"

failed=()
for name in "${TARGETS[@]}"; do
  bin="$build/fuzz_$name"
  corpus="$work/corpus/$name"
  seeds="$work/seeds/$name"
  artifacts="$work/artifacts/$name"
  log="$work/logs/$name.log"
  mkdir -p "$corpus" "$artifacts" "$(dirname "$log")"
  rm -rf "$seeds"
  mkdir -p "$seeds"
  if [ -d "tests/fuzz/seeds/$name" ]; then cp "tests/fuzz/seeds/$name"/* "$seeds"/; fi
  if declare -F "seed_$name" >/dev/null; then "seed_$name" "$seeds"; fi
  args=(-max_total_time="$seconds" -timeout="$timeout" -max_len="$max_len" -detect_leaks=1
        -print_final_stats=1 -artifact_prefix="$artifacts/")
  if [ -f "tests/fuzz/$name.dict" ]; then args+=(-dict="tests/fuzz/$name.dict"); fi
  fork=0
  if [[ "$FORK_TARGETS" == *" $name "* ]]; then
    fork=1
    args+=(-fork=1 -ignore_crashes=1 -ignore_timeouts=1 -ignore_ooms=1)
  fi

  say "fuzz_$name: ${seconds} s, corpus $corpus ($(ls "$corpus" | wc -l) inputs), log $log"
  before=$(ls "$artifacts" | grep -v '^assimp-' || true)
  rc=0
  TIMEFORMAT='%U %S'
  { time "$bin" "${args[@]}" "$corpus" "$seeds" >"$log" 2>&1 || rc=$?; } 2>"$work/time"
  read -r user sys <"$work/time"
  cpu=$(awk -v u="$user" -v s="$sys" 'BEGIN { printf "%.0f", u + s }')
  runs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -n 1)
  if [ "$fork" = 1 ]; then runs=$({ grep -aoE '^#[0-9]+: cov' "$log" || true; } | tail -n 1 | tr -dc 0-9); fi
  cov=$({ grep -aoE 'cov: [0-9]+' "$log" || true; } | tail -n 1 | cut -d' ' -f2)
  result=ok
  known=0
  if [ "$fork" = 1 ]; then
    for f in $(ls "$artifacts" | grep -v '^assimp-' || true); do
      owner=$(owner_of "$bin" "$artifacts/$f")
      # An out-of-memory that the input alone does not reproduce is the
      # memory a fork-mode job gathered over many inputs (assimp's
      # suppressed leaks among it), and a timeout whose input alone ends
      # within six times the limit was the machine's load, not a hang:
      # both kept and listed, not findings.
      if [ "$owner" = assimp ] || { [ "$owner" = clean ] && [[ "$f" == oom-* || "$f" == timeout-* ]]; }; then
        if [ "$owner" = clean ]; then
          case "$f" in oom-*) owner=job-memory ;; *) owner=slow-under-load ;; esac
        fi
        mv "$artifacts/$f" "$artifacts/assimp-$f"
        printf '%s\t%s\t%s\n' "$(date -u +%FT%TZ)" "$owner" "$artifacts/assimp-$f" >>"$work/assimp-findings.tsv"
        known=$((known + 1))
      fi
    done
    if [ "$known" -gt 0 ]; then
      say "fuzz_$name: $known new finding(s) inside assimp, kept as $artifacts/assimp-* (listed in $work/assimp-findings.tsv)"
    fi
  fi
  # New reproducers: those not there before the run (and not assimp's).
  new=$(comm -13 <(printf '%s\n' $before | sort) <(ls "$artifacts" | grep -v '^assimp-' | sort || true) | grep . || true)
  if [ -n "$new" ]; then result=FAILED; fi
  # A run in fork mode that met any crash, ignored or not, exits with 1 once
  # its time is up ("INFO: exiting: 1"): judged by its reproducers above.
  # Any other way of ending is a failure.
  if [ "$rc" -ne 0 ] && { [ "$fork" = 0 ] || ! tail -n 1 "$log" | grep -q '^INFO: exiting: '; }; then result=FAILED; fi
  if [ "$result" = ok ]; then
    # libFuzzer adds a file for every input that reached new code and keeps
    # the ones a shorter input replaced: keep only a set with the same
    # coverage (-merge=1), so the corpus does not grow from run to run.
    merged="$work/corpus/$name.merged"
    rm -rf "$merged"
    mkdir -p "$merged"
    if "$bin" -merge=1 -timeout="$timeout" -max_len="$max_len" "$merged" "$corpus" >"$work/logs/$name.merge.log" 2>&1; then
      rm -rf "$corpus"
      mv "$merged" "$corpus"
    else
      rm -rf "$merged"
    fi
  fi
  size=$(ls "$corpus" | wc -l)
  printf '%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\n' "$(date -u +%FT%TZ)" "$name" "$seconds" "$cpu" \
    "${runs:-0}" "${cov:-0}" "$size" "$result" >>"$work/history.tsv"
  say "fuzz_$name: $result: ${runs:-0} executions in ${cpu} CPU s, coverage ${cov:-0} edges, corpus $size inputs"
  if [ "$result" != ok ]; then
    failed+=("$name")
    grep -aE '^(==[0-9]+==ERROR|SUMMARY|fuzz check failed|.*runtime error)' "$log" | head -n 5 >&2 || true
    for f in $new; do
      say "reproducer: $artifacts/$f  (run: $bin $artifacts/$f)"
    done
    say "full report: $log"
  fi
done

if [ ${#failed[@]} -ne 0 ]; then
  say "FAILED: ${failed[*]}"
  exit 1
fi
say "all targets ran clean"
