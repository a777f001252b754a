#!/usr/bin/env bash
# The main job: start voxvis-server on examples/paper (5,000 spheres, 200 of
# them moving), walk a viewer through its 300 frames over the socket with
# `voxvis view` (moves go through a simulation stream), print a summary of
# every 30th frame, check the answers against the offline `voxvis replay`, and
# stop the server with SIGTERM. Needs a build in build/ (deploy/setup.sh).
set -euo pipefail
cd "$(dirname "$0")/.."

work=build/demo
rm -rf "$work"
mkdir -p "$work"

echo "voxvis: starting voxvis-server on examples/paper/scene.json" >&2
build/voxvis-server --listen 127.0.0.1:0 --port-file "$work/port" --data-dir "$work/data" \
  --scene paper=examples/paper/scene.json 2>"$work/server.log" &
server=$!
stop_server() {
  if kill -0 "$server" 2>/dev/null; then
    kill -TERM "$server"
    wait "$server" || true
  fi
}
trap stop_server EXIT

for _ in $(seq 1 300); do
  [ -s "$work/port" ] && break
  kill -0 "$server" 2>/dev/null || break
  sleep 0.1
done
if [ ! -s "$work/port" ]; then
  echo "voxvis: the server did not start:" >&2
  cat "$work/server.log" >&2
  exit 1
fi
address="127.0.0.1:$(cat "$work/port")"
echo "voxvis: server listening on $address; walking through examples/paper/frames.jsonl" >&2

build/voxvis view --server "$address" --scene paper --frames examples/paper/frames.jsonl \
  --out "$work/paper-view.jsonl" --every 30

kill -TERM "$server"
status=0
wait "$server" || status=$?
trap - EXIT
if [ "$status" -ne 0 ]; then
  echo "voxvis: the server exited with status $status:" >&2
  cat "$work/server.log" >&2
  exit 1
fi
echo "voxvis: server stopped (SIGTERM, exit 0); its log is in $work/server.log" >&2

# The same walkthrough offline: the answers must be the same PVS and wake lists.
build/voxvis replay --scene examples/paper/scene.json --frames examples/paper/frames.jsonl \
  --out "$work/paper-replay.jsonl" --quiet
# Every time (time_us and its split, traverse_us, render_us, retest_us) differs run to run.
strip_times() { sed -E -e 's/"[a-z_]*_us":[0-9.e+-]*,//g' "$1"; }
if cmp -s <(strip_times "$work/paper-view.jsonl") <(strip_times "$work/paper-replay.jsonl"); then
  echo "voxvis: all 300 answers over the socket match the offline replay" >&2
else
  echo "voxvis: answers over the socket differ from the offline replay" >&2
  exit 1
fi
# And checked: every object that shows at 640x360 (rendered headlessly through
# EGL) must be in the answer the server gave.
if build/voxvis verify --scene examples/paper/scene.json --frames examples/paper/frames.jsonl \
  --pvs "$work/paper-view.jsonl" --resolution 640x360 --out "$work/paper-verify.jsonl"; then
  echo "voxvis: no visible object missing from any of the 300 answers" >&2
else
  echo "voxvis: verification found misses (or could not render): see above" >&2
  exit 1
fi
echo "voxvis: per-frame answers in $work/paper-view.jsonl, their verification in $work/paper-verify.jsonl" >&2
