#!/usr/bin/env bash
# deploy/image.sh — builds the voxvis container image (deploy/Containerfile)
# on a machine without a reachable image registry: the Debian 12 base is made
# from Debian's archive with debootstrap and imported as
# localhost/debian:bookworm (once), then the image is built on it and tagged
# localhost/voxvis:VERSION and localhost/voxvis:latest.
#
#   bash deploy/image.sh                # build (installs podman, runc, debootstrap if missing)
#   VOXVIS_IMAGE=my/voxvis bash deploy/image.sh
#   bash deploy/image.sh --binaries build   # the runtime stage around this machine's
#                                           # Release build of voxvis-server and voxvis
#
# --binaries DIR skips the image's build stage (its packages and compiling
# voxvis: most of the image's time): DIR's voxvis-server and voxvis, built on
# Debian 12 as deploy/setup.sh builds them, are stripped into deploy/.prebuilt/
# with the packages they load (deploy/runtime_packages.sh) and the runtime
# stage is built around them. The test suite's container stage does this with
# its Release build; without --binaries the image compiles its own, as shipped.
#
# Where a registry is reachable, `podman build -f deploy/Containerfile .`
# (FROM debian:12) works as it is. podman runs with runc and explicit
# ulimits: its default runtime (crun) fails on hosts with hybrid cgroups, and
# its default limits may exceed the host's (docs/deploy.md).
set -euo pipefail
cd "$(dirname "$0")/.."

binaries=""
while [ $# -gt 0 ]; do
  case "$1" in
    --binaries)
      [ $# -ge 2 ] || { echo "voxvis image: error: --binaries needs a directory" >&2; exit 2; }
      binaries="$2"; shift 2 ;;
    -h|--help) sed -n '2,/^set -euo/p' "$0" | sed '$d; s/^# \{0,1\}//'; exit 0 ;;
    *) echo "voxvis image: error: unknown argument '$1' (usage: deploy/image.sh [--binaries DIR])" >&2; exit 2 ;;
  esac
done
if [ -n "$binaries" ]; then
  for b in voxvis-server voxvis; do
    [ -x "$binaries/$b" ] || { echo "voxvis image: error: --binaries $binaries: no executable $binaries/$b (build it first: cmake --build $binaries)" >&2; exit 2; }
  done
fi

image="${VOXVIS_IMAGE:-localhost/voxvis}"
base="localhost/debian:bookworm"
version=$(sed -n 's/^project(voxvis VERSION \([0-9.]*\).*/\1/p' CMakeLists.txt)
mirror="${VOXVIS_DEBIAN_MIRROR:-http://deb.debian.org/debian}"
start=$(date +%s)
say() { echo "voxvis image: $*" >&2; }

need=()
for tool in podman runc debootstrap; do command -v "$tool" >/dev/null 2>&1 || need+=("$tool"); done
if [ ${#need[@]} -gt 0 ]; then
  if [ "$(id -u)" -ne 0 ]; then
    say "error: ${need[*]} missing and not root: install them with apt-get" && exit 2
  fi
  say "installing ${need[*]}"
  DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends "${need[@]}" >&2
fi
# The same settings on every podman command (../docs/deploy.md, "Container").
podman_args=(--runtime runc)
build_args=(--ulimit nofile=20000:20000 --ulimit nproc=4096:4096)

if podman image exists "$base"; then
  say "base $base present"
else
  if [ "$(id -u)" -ne 0 ]; then say "error: making the base image with debootstrap needs root" && exit 2; fi
  rootfs=$(mktemp -d /var/tmp/voxvis-rootfs.XXXXXX)
  trap 'rm -rf "$rootfs"' EXIT
  say "making $base with debootstrap from $mirror (about 2 minutes)"
  debootstrap --variant=minbase bookworm "$rootfs" "$mirror" >&2
  tar -C "$rootfs" -c . | podman "${podman_args[@]}" import - "$base" >/dev/null
  rm -rf "$rootfs"
  trap - EXIT
fi

if [ -n "$binaries" ]; then
  prebuilt=deploy/.prebuilt
  rm -rf "$prebuilt" && mkdir -p "$prebuilt"
  trap 'rm -rf "$prebuilt"' EXIT
  for b in voxvis-server voxvis; do strip -o "$prebuilt/$b" "$binaries/$b"; done
  bash deploy/runtime_packages.sh "$prebuilt/voxvis-server" "$prebuilt/voxvis" >"$prebuilt/runtime-packages"
  build_args+=(--build-arg BINARIES=prebuilt)
  say "building $image:$version from deploy/Containerfile around $binaries/voxvis-server and $binaries/voxvis"
else
  say "building $image:$version from deploy/Containerfile (compiles voxvis: several minutes on 2 cores)"
fi
# docker format keeps the HEALTHCHECK (OCI images have no such field);
# host network: the build's apt-get reaches Debian's archive as this machine does.
podman "${podman_args[@]}" build --format docker --network host "${build_args[@]}" \
  --build-arg BASE="$base" -f deploy/Containerfile -t "$image:$version" -t "$image:latest" .
say "built $image:$version and $image:latest in $(( $(date +%s) - start )) s"
podman "${podman_args[@]}" image ls "$image" >&2
