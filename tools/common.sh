# Shared by tools/demo and tools/test: install missing Debian packages, then configure and build.
# Idempotent and non-interactive. Source it; do not run it.
set -euo pipefail

ARTHROSIM_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"

# Everything the build, the tests and the demo need, from Debian bookworm.
ARTHROSIM_PACKAGES=(
  build-essential cmake ninja-build pkg-config ccache
  libeigen3-dev libsundials-dev libfcl-dev libosmesa6-dev libhdf5-dev hdf5-tools zlib1g-dev
  libyaml-cpp-dev libcli11-dev libfmt-dev libgtest-dev libgmock-dev libbenchmark-dev
  libopenigtlink-dev libstb-dev fonts-dejavu-core ffmpeg chromium
  python3 python3-h5py python3-numpy python3-yaml gmsh python3-gmsh
)

# What tools/fuzz needs on top: clang and its libFuzzer / sanitizer runtimes.
ARTHROSIM_FUZZ_PACKAGES=(clang-14 libclang-rt-14-dev)

# arthrosim_install_packages [PACKAGE...]: installs those missing of the given packages
# (default: ARTHROSIM_PACKAGES).
arthrosim_install_packages() {
  local missing=() wanted=("$@")
  if [ ${#wanted[@]} -eq 0 ]; then wanted=("${ARTHROSIM_PACKAGES[@]}"); fi
  for p in "${wanted[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
  if [ ${#missing[@]} -eq 0 ]; then return 0; fi
  echo "arthrosim: installing ${missing[*]}" >&2
  local sudo=""
  if [ "$(id -u)" -ne 0 ]; then sudo="sudo"; fi
  export DEBIAN_FRONTEND=noninteractive
  $sudo apt-get update -qq
  $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
}

# arthrosim_build BUILD_DIR [cmake args...]: configure (once) and build everything.
# ccache sees paths relative to the checkout's parent folder and not the build folder's path, so
# two checkouts (a CI clone, a git worktree) share one cache; a user's own settings win.
arthrosim_build() {
  local dir="$1"; shift
  export CCACHE_BASEDIR="${CCACHE_BASEDIR:-$(dirname "$ARTHROSIM_ROOT")}"
  export CCACHE_NOHASHDIR="${CCACHE_NOHASHDIR:-1}"
  cmake -S "$ARTHROSIM_ROOT" -B "$dir" -G Ninja -DCMAKE_BUILD_TYPE=Release \
        -DCMAKE_CXX_COMPILER_LAUNCHER=ccache "$@" >/dev/null
  cmake --build "$dir" -j "$(nproc)"
}
