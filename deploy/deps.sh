# deploy/deps.sh — sourced by deploy/setup.sh and tests/run.sh.
# Installs the Debian 12 packages voxvis builds with, when any is missing.
# Every dependency comes from Debian's archive; nothing is downloaded otherwise.

VOXVIS_PACKAGES=(
  build-essential cmake ninja-build pkg-config
  libglm-dev nlohmann-json3-dev libcli11-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  clang libclang-rt-14-dev llvm
  libgrpc++-dev libprotobuf-dev protobuf-compiler protobuf-compiler-grpc grpc-proto prometheus-cpp-dev
  libcurl4-openssl-dev libssl-dev
  openssl
  libegl-dev libopengl-dev libgl-dev libegl-mesa0 libgl1-mesa-dri
  gnuplot-nox
  python3-grpcio python3-protobuf
  libopenvdb-dev libboost-iostreams-dev
  libassimp-dev
)

# Only the test suite uses these (tests/run.sh installs them; the tests that
# need one skip with a message when it is missing): real model files for the
# importer's tests (glTF 2.0 samples, OBJ, the FZK house as IFC) in
# /usr/share/assimp/models.
VOXVIS_TEST_PACKAGES=(
  assimp-testmodels
)

# voxvis_ensure_deps [tests]: the build's packages, and with `tests` the test
# suite's as well.
voxvis_ensure_deps() {
  local missing=()
  local p
  local wanted=("${VOXVIS_PACKAGES[@]}")
  if [ "${1:-}" = tests ]; then wanted+=("${VOXVIS_TEST_PACKAGES[@]}"); fi
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
