#!/usr/bin/env bash
# deploy/runtime_packages.sh BINARY... — prints, one per line, the Debian
# packages a runtime image needs for these binaries: those that own the
# libraries they load (ldd), and Mesa's EGL vendor and llvmpipe, which EGL
# opens by name at run time (`voxvis verify`, the server's verify mode).
# Run where the binaries were linked (the image's build stage, or the
# machine whose build deploy/image.sh --binaries packs), so the list never
# drifts from what was linked.
set -euo pipefail
[ $# -gt 0 ] || { echo "usage: deploy/runtime_packages.sh BINARY..." >&2; exit 2; }
for b in "$@"; do
  [ -x "$b" ] || { echo "deploy/runtime_packages.sh: $b is not an executable file" >&2; exit 2; }
done
libs=$(for b in "$@"; do ldd "$b"; done | awk '$2 == "=>" && $3 ~ /^\// { print $3 }' | sort -u)
{
  while read -r lib; do
    [ -n "$lib" ] || continue
    dpkg -S "$(readlink -f "$lib")" 2>/dev/null || dpkg -S "$lib" ||
      { echo "deploy/runtime_packages.sh: no package owns $lib" >&2; exit 1; }
  done <<<"$libs" | cut -d: -f1
  echo libegl-mesa0
  echo libgl1-mesa-dri
} | sort -u
