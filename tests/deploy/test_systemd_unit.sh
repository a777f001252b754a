#!/usr/bin/env bash
# tests/deploy/test_systemd_unit.sh BUILD_DIR — deploy/voxvis-server.service
# passes `systemd-analyze verify` without a single complaint (it exits 0 on
# unknown keys and bad values, printing them, so any output fails here), with
# ExecStart pointed at BUILD_DIR's voxvis-server (verify checks that it is
# executable). Then a unit with a misspelt key must be complained about, so a
# silent verifier cannot pass the test. Exit 77 (skipped) without systemd-analyze.
set -euo pipefail
build=$(cd "${1:?usage: $0 BUILD_DIR}" && pwd)
unit="$(dirname "$0")/../../deploy/voxvis-server.service"
if ! command -v systemd-analyze >/dev/null 2>&1; then
  echo "SKIPPED: systemd-analyze not found (Debian package systemd)"
  exit 77
fi
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
sed "s#/usr/local/bin/voxvis-server#$build/voxvis-server#" "$unit" > "$work/voxvis-server.service"
grep -q "^ExecStart=$build/voxvis-server " "$work/voxvis-server.service" \
  || { echo "FAIL: ExecStart does not run /usr/local/bin/voxvis-server"; exit 1; }
out=$(systemd-analyze verify "$work/voxvis-server.service" 2>&1) || { echo "FAIL: $out"; exit 1; }
[ -z "$out" ] || { echo "FAIL: systemd-analyze verify complains:"; echo "$out"; exit 1; }
echo "voxvis-server.service: systemd-analyze verify: no complaint"

sed 's/^ProtectHome=/ProtectHom=/' "$work/voxvis-server.service" > "$work/broken.service"
out=$(systemd-analyze verify "$work/broken.service" 2>&1 || true)
grep -q "Unknown key 'ProtectHom'" <<<"$out" \
  || { echo "FAIL: a misspelt key went unreported (output: $out)"; exit 1; }
echo "a misspelt key is reported"
