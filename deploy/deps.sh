# deploy/deps.sh — sourced by deploy/setup.sh and tests/run.sh.
# Installs the Debian 12 packages voxvis builds with, when any is missing.
# Every dependency comes from Debian's archive; nothing is downloaded otherwise.

# What building voxvis-server and voxvis needs (the container image's build
# stage installs these alone: deploy/Containerfile).
VOXVIS_BUILD_PACKAGES=(
  build-essential cmake ninja-build pkg-config
  libglm-dev nlohmann-json3-dev libcli11-dev
  libgrpc++-dev libprotobuf-dev protobuf-compiler protobuf-compiler-grpc grpc-proto prometheus-cpp-dev
  libcurl4-openssl-dev libssl-dev
  libegl-dev libopengl-dev libgl-dev libegl-mesa0 libgl1-mesa-dri
  libopenvdb-dev libboost-iostreams-dev
  libassimp-dev
)

# The rest of a development machine's: the test suite and benchmarks, the
# fuzz targets (clang), the TLS test's certificates, `voxvis report`'s plot,
# the Python example's client.
VOXVIS_DEV_PACKAGES=(
  libgtest-dev libgmock-dev libbenchmark-dev
  clang libclang-rt-14-dev llvm
  openssl
  gnuplot-nox
  python3-grpcio python3-protobuf
)

VOXVIS_PACKAGES=("${VOXVIS_BUILD_PACKAGES[@]}" "${VOXVIS_DEV_PACKAGES[@]}")

# Only the test suite uses these (tests/run.sh installs them; the tests that
# need one skip with a message when it is missing): real model files for the
# importer's tests (glTF 2.0 samples, OBJ, the FZK house as IFC) in
# /usr/share/assimp/models; podman, runc and debootstrap for the container
# image's test (tests/deploy/container_test.sh; runc because podman's default
# runtime, crun, fails on hosts with hybrid cgroups; catatonit because
# `podman kube play` builds its pod's pause image from it, and it is only a
# recommendation of podman's, which --no-install-recommends leaves out); PyYAML and Debian's
# Kubernetes client, whose models are the API's schema, for the manifests'
# check (tests/deploy/test_manifests.py).
VOXVIS_TEST_PACKAGES=(
  assimp-testmodels
  podman runc catatonit debootstrap
  python3-yaml python3-kubernetes
)

# voxvis_ensure_deps [tests|build]: a development machine's packages; with
# `tests` the test suite's as well; with `build` only what building the two
# binaries needs (the container image).
voxvis_ensure_deps() {
  local missing=()
  local p
  local wanted=("${VOXVIS_PACKAGES[@]}")
  if [ "${1:-}" = tests ]; then wanted+=("${VOXVIS_TEST_PACKAGES[@]}"); fi
  if [ "${1:-}" = build ]; then wanted=("${VOXVIS_BUILD_PACKAGES[@]}"); fi
  for p in "${wanted[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
  if [ ${#missing[@]} -eq 0 ]; then
    return 0
  fi
  echo "voxvis: installing missing packages: ${missing[*]}" >&2
  local sudo=()
  if [ "$(id -u)" -ne 0 ]; then
    if command -v sudo >/dev/null 2>&1; then
      sudo=(sudo)
    else
      echo "voxvis: error: packages missing (${missing[*]}) and not root; install them with apt-get" >&2
      return 1
    fi
  fi
  "${sudo[@]}" env DEBIAN_FRONTEND=noninteractive apt-get update -q
  "${sudo[@]}" env DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends "${missing[@]}"
}
