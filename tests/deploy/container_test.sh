#!/usr/bin/env bash
# tests/deploy/container_test.sh — the container image and the manifests that
# podman can play, on this machine:
#  1. `bash deploy/image.sh` builds the image: around the Release build's
#     binaries (`--binaries build`), or compiling them in the image's build
#     stage, as shipped, when that stage's inputs changed since it last
#     passed here (see "The image" below) or VOXVIS_IMAGE_FROM_SOURCE=1;
#  2. the image serves the bundled walkthrough: health SERVING, `voxvis view`
#     answers equal `voxvis replay`'s, and SIGTERM (`podman stop`) ends it with
#     exit 0 within the grace period;
#  3. `podman kube play` of deploy/k8s/sidecar.yaml (the stand-in game server
#     walks the walkthrough over localhost), server-deployment.yaml (serves,
#     answers as replay) and the verify Job's pod (verify-job.yaml's template
#     with JOB_COMPLETION_INDEX set: its slice is written, nothing missed);
#     each is stopped with `podman kube down`.
# Runs from tests/run.sh after the Release build (it uses build/voxvis on the
# host side). When podman cannot run here it says why, prints SKIPPED and
# exits 0: never a silent pass. Everything it made is removed at the end.
set -euo pipefail
cd "$(dirname "$0")/../.."
root=$(pwd)
cli="$root/build/voxvis"
# An image name of the test's own: the test never replaces a localhost/voxvis
# the machine has (it keeps localhost/voxvis-test, whose layers a later run
# reuses; `podman rmi localhost/voxvis-test` frees its space).
export VOXVIS_IMAGE=localhost/voxvis-test
image="$VOXVIS_IMAGE:latest"
start=$(date +%s)
say() { echo "container test: $*" >&2; }
skip() { say "SKIPPED: $*"; exit 0; }
fail() { say "FAILED: $*"; exit 1; }

[ -x "$cli" ] || fail "$cli missing: build first (tests/run.sh does)"
command -v podman >/dev/null 2>&1 || skip "podman is not installed (deploy/deps.sh's test packages install it as root)"
command -v runc >/dev/null 2>&1 || skip "runc is not installed"
# `podman kube play` builds its pods' pause image from catatonit, which podman
# only recommends: without it every kube play fails after the long build.
command -v catatonit >/dev/null 2>&1 || skip "catatonit is not installed (podman kube play needs it; deploy/deps.sh's test packages install it)"
work=$(mktemp -d /tmp/voxvis-container-test.XXXXXX)
# podman's settings for every command, kube play included (it takes no
# --ulimit): runc, and limits within the host's hard ones (podman's defaults
# may exceed them).
nofile=$(ulimit -Hn); nproc=$(ulimit -Hu)
[ "$nofile" = unlimited ] && nofile=1048576
[ "$nproc" = unlimited ] && nproc=65536
[ "$nproc" -gt 4096 ] && nproc=4096
cat >"$work/containers.conf" <<CONF
[containers]
default_ulimits = ["nofile=$nofile:$nofile", "nproc=$nproc:$nproc"]
[engine]
runtime = "runc"
CONF
export CONTAINERS_CONF="$work/containers.conf"
podman=(podman)
run_flags=(--health-interval=disable)
# A throwaway container tells whether podman can run anything here at all
# (storage, cgroups) before the long build.
if ! why=$("${podman[@]}" info 2>&1 >/dev/null); then
  rm -rf "$work"
  skip "podman cannot run here: $(echo "$why" | tail -1)"
fi

name="voxvis-test-$$"
cleanup() {
  "${podman[@]}" rm -f -t 0 "$name" >/dev/null 2>&1 || true
  for f in "$work"/*.play.yaml; do
    [ -e "$f" ] && "${podman[@]}" kube down "$f" >/dev/null 2>&1 || true
  done
  "${podman[@]}" volume rm -f "$name-run" "$name-data" "$name-results" >/dev/null 2>&1 || true
  rm -rf "$work"
}
trap cleanup EXIT

# --- 1. The image.
# The build stage (its packages, compiling voxvis in the image) costs most of
# this test's time and checks nothing the Release build has not, except the
# stage's own inputs: the Containerfile, the package lists and the runtime
# package computation. Their hash when a build from source last passed is
# kept in image-build-checked.sha256; while they still hash to it, the image
# is built around build/'s binaries. A change to them makes the next run
# build from source, and its pass records the new hash (commit the file).
checked_file=tests/deploy/image-build-checked.sha256
inputs=(deploy/Containerfile deploy/deps.sh deploy/runtime_packages.sh .containerignore)
inputs_hash=$(cat "${inputs[@]}" | sha256sum | cut -d' ' -f1)
image_args=(--binaries build)
if [ "${VOXVIS_IMAGE_FROM_SOURCE:-0}" = 1 ]; then
  image_args=()
  say "building the image from source (VOXVIS_IMAGE_FROM_SOURCE=1)"
elif [ "$(cat "$checked_file" 2>/dev/null)" != "$inputs_hash" ]; then
  image_args=()
  say "building the image from source: ${inputs[*]} changed since $checked_file was recorded"
else
  say "building the image around build/'s binaries (deploy/image.sh --binaries build)"
fi
if [ "$(id -u)" -ne 0 ] && ! "${podman[@]}" image exists localhost/debian:bookworm; then
  skip "not root: deploy/image.sh needs root to make the Debian base with debootstrap"
fi
if ! bash deploy/image.sh "${image_args[@]}" >"$work/image.log" 2>&1; then
  # Can podman run a container here at all? If not, this machine cannot run
  # the test; if it can, the image's build failed.
  if "${podman[@]}" image exists localhost/debian:bookworm &&
     ! why=$("${podman[@]}" run --rm "${run_flags[@]}" --network none localhost/debian:bookworm true 2>&1); then
    skip "podman cannot run a container here: $(echo "$why" | grep -v level= | tail -1)"
  fi
  tail -30 "$work/image.log" >&2
  fail "deploy/image.sh failed"
fi
# (Outputs are read whole before grep: under pipefail, `grep -q` leaving
# early would fail the pipe with the writer's SIGPIPE.)
version=$("${podman[@]}" run --rm "${run_flags[@]}" --network none "$image" --version 2>/dev/null || true)
grep -q '^voxvis-server ' <<<"$version" || fail "the image's entry point is not voxvis-server (got: $version)"
uid=$("${podman[@]}" run --rm "${run_flags[@]}" --network none --entrypoint id "$image" -u 2>/dev/null)
[ "$uid" != 0 ] || fail "the image runs as root"

# The same frames replayed offline: what every serving form must answer.
frames="$work/frames.jsonl"
head -n 60 examples/paper/frames.jsonl >"$frames"
"$cli" replay --scene examples/paper/scene.json --frames "$frames" --out "$work/replay.jsonl" -q
same_as_replay() {  # FILE WHAT: frame, pvs, wake and counters equal replay's (times aside)
  python3 - "$work/replay.jsonl" "$1" "$2" <<'PY'
import json, sys
def strip(path):
    out = []
    for line in open(path):
        j = json.loads(line)
        s = j.get("stats", {})
        j["stats"] = {k: v for k, v in s.items() if not (k.endswith("_us") or k.endswith("_ms"))}
        out.append(j)
    return out
a, b = strip(sys.argv[1]), strip(sys.argv[2])
if a != b:
    bad = next((i for i, (x, y) in enumerate(zip(a, b)) if x != y), min(len(a), len(b)))
    sys.exit(f"{sys.argv[3]}: line {bad + 1} differs from replay's ({len(b)} lines, replay {len(a)})")
PY
}
wait_serving() {  # ADDRESS SECONDS [CONTAINER]: SERVING within SECONDS; gives up at once if CONTAINER exits
  local end=$(( $(date +%s) + $2 ))
  while [ "$(date +%s)" -lt "$end" ]; do
    "$cli" health --server "$1" --timeout 2 >/dev/null 2>&1 && return 0
    if [ -n "${3:-}" ] && [ "$("${podman[@]}" inspect -f '{{.State.Running}}' "$3" 2>/dev/null)" != true ]; then
      say "$3 is not running"
      return 1
    fi
  done
  return 1
}

# --- 2. The image serves the walkthrough; SIGTERM stops it gracefully.
say "serving the walkthrough from the image"
"${podman[@]}" run -d --name "$name" "${run_flags[@]}" -p 127.0.0.1::50051 -v "$name-run":/data \
  "$image" --scene paper=/usr/share/voxvis/examples/paper/scene.json >/dev/null 2>"$work/run.err" \
  || { cat "$work/run.err" >&2; fail "podman run failed"; }
port=$("${podman[@]}" port "$name" 50051/tcp | sed 's/.*://')
[ -n "$port" ] || fail "no published port"
wait_serving "127.0.0.1:$port" 60 "$name" || { "${podman[@]}" logs "$name" >&2; fail "health not SERVING"; }
[ "$("$cli" health --server "127.0.0.1:$port")" = SERVING ] || fail "health did not print SERVING"
"${podman[@]}" healthcheck run "$name" >/dev/null 2>&1 || fail "the image's HEALTHCHECK failed while serving"
"$cli" view --server "127.0.0.1:$port" --scene paper --frames "$frames" --out "$work/view.jsonl" -q \
  || fail "voxvis view against the container failed"
same_as_replay "$work/view.jsonl" "voxvis view (container)" || fail "the container's answers differ from replay's"
grace=30
t0=$(date +%s%N)
"${podman[@]}" stop -t "$grace" "$name" >/dev/null 2>&1
elapsed_ms=$(( ($(date +%s%N) - t0) / 1000000 ))
code=$("${podman[@]}" inspect -f '{{.State.ExitCode}}' "$name")
[ "$code" = 0 ] || { "${podman[@]}" logs "$name" >&2; fail "exit status $code after SIGTERM (expected 0)"; }
[ "$elapsed_ms" -lt $((grace * 1000)) ] || fail "the stop took ${elapsed_ms} ms, over the ${grace} s grace"
log=$("${podman[@]}" logs "$name" 2>&1)
grep -q "received SIGTERM" <<<"$log" || fail "the server did not log the SIGTERM"
say "stopped by SIGTERM in ${elapsed_ms} ms, exit 0"
"${podman[@]}" rm -f "$name" >/dev/null

# --- 3. Manifests under podman kube play.
play() {  # FILE: plays it (kept for cleanup as *.play.yaml)
  "${podman[@]}" kube play "$1" >"$work/play.log" 2>&1 || { cat "$work/play.log" >&2; fail "kube play $1 failed"; }
}
down() { "${podman[@]}" kube down "$1" >/dev/null 2>&1 || fail "kube down $1 failed"; }

say "kube play: sidecar.yaml"
sed "s#localhost/voxvis:latest#$image#" deploy/k8s/sidecar.yaml >"$work/sidecar.play.yaml"
play "$work/sidecar.play.yaml"
ok=0
for _ in $(seq 120); do
  log=$("${podman[@]}" logs match-1-game-server 2>&1 || true)
  if grep -q "walkthrough answered" <<<"$log"; then ok=1; break; fi
  sleep 1
done
[ "$ok" = 1 ] || { "${podman[@]}" logs match-1-game-server >&2 || true; "${podman[@]}" logs match-1-voxvis >&2 || true;
                   fail "the sidecar's game server got no answers over localhost"; }
down "$work/sidecar.play.yaml"

say "kube play: server-deployment.yaml"
# Free host ports in place of 50051 and 9090 (the machine may use them).
free_port() { python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'; }
free=$(free_port); free_metrics=$(free_port)
# Volumes of the test's own (podman keeps a claim's volume after kube down).
sed -e "s/hostPort: 50051/hostPort: $free/" -e "s/hostPort: 9090/hostPort: $free_metrics/" \
  -e "s/voxvis-data/$name-data/" -e "s#localhost/voxvis:latest#$image#" \
  deploy/k8s/server-deployment.yaml >"$work/server.play.yaml"
play "$work/server.play.yaml"
wait_serving "127.0.0.1:$free" 90 voxvis-pod-0-voxvis || { "${podman[@]}" logs voxvis-pod-0-voxvis >&2 || true;
  fail "the Deployment's server is not SERVING on port $free"; }
"$cli" view --server "127.0.0.1:$free" --scene paper --frames "$frames" --out "$work/deploy-view.jsonl" -q \
  || fail "voxvis view against the Deployment failed"
same_as_replay "$work/deploy-view.jsonl" "voxvis view (Deployment)" || fail "the Deployment's answers differ from replay's"
# The metrics the scrape annotations point at.
python3 -c "import urllib.request,sys; t=urllib.request.urlopen('http://127.0.0.1:$free_metrics/metrics', timeout=10).read().decode(); sys.exit(0 if 'voxvis_frames_total' in t else 1)" \
  || fail "no voxvis metrics at the Deployment's metrics port"
down "$work/server.play.yaml"

say "kube play: the verify Job's pod (slice 1 of 10 frames)"
# podman plays Pods, not Jobs: the Job's pod template as a Pod, with what
# Kubernetes would set (JOB_COMPLETION_INDEX) and a shorter slice.
python3 - deploy/k8s/verify-job.yaml "$work/verify.play.yaml" "$name-results" "$image" <<'PY'
import sys, yaml
docs = [d for d in yaml.safe_load_all(open(sys.argv[1])) if d]
pvc = next(d for d in docs if d["kind"] == "PersistentVolumeClaim")
job = next(d for d in docs if d["kind"] == "Job")
spec = job["spec"]["template"]["spec"]
pvc["metadata"]["name"] = sys.argv[3]
for v in spec["volumes"]:
    if "persistentVolumeClaim" in v:
        v["persistentVolumeClaim"]["claimName"] = sys.argv[3]
for c in spec["containers"]:
    c["image"] = sys.argv[4]
    env = [e for e in c.get("env", []) if e["name"] != "SLICE_FRAMES"]
    c["env"] = env + [{"name": "SLICE_FRAMES", "value": "10"}, {"name": "JOB_COMPLETION_INDEX", "value": "1"}]
pod = {"apiVersion": "v1", "kind": "Pod",
       "metadata": {"name": "voxvis-verify-1", "labels": job["spec"]["template"]["metadata"]["labels"]},
       "spec": spec}
yaml.safe_dump_all([pvc, pod], open(sys.argv[2], "w"))
PY
t0=$(date +%s)
play "$work/verify.play.yaml"
"${podman[@]}" wait voxvis-verify-1-verify >"$work/verify.code" 2>/dev/null || true
code=$(cat "$work/verify.code")
[ "$code" = 0 ] || { "${podman[@]}" logs voxvis-verify-1-verify >&2 || true; fail "the verify pod exited $code"; }
volume=$("${podman[@]}" volume inspect -f '{{.Mountpoint}}' "$name-results")
slice="$volume/slice-0001.jsonl"
[ -f "$slice" ] || fail "the verify pod wrote no $slice"
"$cli" verify-merge "$slice" --out "$work/slice.jsonl" 2>"$work/merge.log" || { cat "$work/merge.log" >&2; fail "the slice has misses or is malformed"; }
[ "$(wc -l <"$work/slice.jsonl")" = 10 ] || fail "the slice has $(wc -l <"$work/slice.jsonl") lines, not 10"
[ "$(head -c 12 "$work/slice.jsonl")" = '{"frame":10,' ] || fail "slice 1 does not start at frame 10"
# The pod's slice is the host's verify of the same frames (timings aside).
"$cli" verify --scene examples/paper/scene.json --frames examples/paper/frames.jsonl --first-frame 10 \
  --frame-count 10 --resolution 640x360 --out "$work/host-slice.jsonl" -q || fail "the host's verify of frames 10-19 failed"
python3 - "$work/host-slice.jsonl" "$work/slice.jsonl" <<'PY' || fail "the pod's slice differs from the host's verify"
import json, sys
def load(p):
    return [{k: v for k, v in json.loads(l).items() if k != "stats"} for l in open(p)]
a, b = load(sys.argv[1]), load(sys.argv[2])
sys.exit(0 if a == b else f"host {a[:1]} ... vs pod {b[:1]} ...")
PY
say "verify slice of 10 frames at 640x360 in the pod: $(( $(date +%s) - t0 )) s ($(cat "$work/merge.log" | sed 's/^voxvis: //'))"
down "$work/verify.play.yaml"

if [ ${#image_args[@]} -eq 0 ]; then
  echo "$inputs_hash" >"$checked_file"
  say "the image's build stage passed: recorded its inputs' hash in $checked_file (commit it)"
fi
say "passed in $(( $(date +%s) - start )) s"
