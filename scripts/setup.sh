#!/usr/bin/env bash
# Installs the Debian packages causaldrive needs; does nothing when they are all present.
# OpenMPI is optional to the build (CMakeLists.txt: collect/eval under mpirun); it is installed
# here so that the MPI tests run.
set -euo pipefail

packages=(
  build-essential cmake pkg-config ninja-build
  sumo sumo-tools
  libtorch-dev libopenblas0-openmp
  libeigen3-dev libboost-math-dev
  libhdf5-dev zlib1g-dev
  libtomlplusplus-dev libcli11-dev nlohmann-json3-dev
  libstb-dev
  libmujoco-dev libosmesa6-dev
  libgtest-dev libbenchmark-dev
  python3 python3-dev python3-numpy python3-h5py python3-statsmodels python3-torch
  pybind11-dev python3-pybind11
  libopenmpi-dev openmpi-bin
  chromium
)

# The HTML report's browser test drives Debian's chromium with playwright-core (npm, pinned in
# tests/browser/package-lock.json); Node.js from Debian when the machine has none.
command -v node >/dev/null && command -v npm >/dev/null || packages+=(nodejs npm)

missing=()
for p in "${packages[@]}"; do
  status=$(dpkg-query -W -f='${Status}' "$p" 2>/dev/null || true)
  [[ "$status" == "install ok installed" ]] || missing+=("$p")
done

browser_deps() {
  local dir
  dir="$(dirname "$0")/../tests/browser"
  [[ -d $dir/node_modules/playwright-core ]] && return 0
  echo "setup: installing the browser test's playwright-core (npm ci in tests/browser)"
  (cd "$dir" && npm ci --no-audit --no-fund --loglevel=error)
}

if [[ ${#missing[@]} -eq 0 ]]; then
  browser_deps
  exit 0
fi

echo "setup: installing ${#missing[@]} missing package(s): ${missing[*]}"
sudo=""
if [[ $(id -u) -ne 0 ]]; then
  command -v sudo >/dev/null || { echo "setup: need root or sudo to install: ${missing[*]}" >&2; exit 1; }
  sudo="sudo"
fi
export DEBIAN_FRONTEND=noninteractive
$sudo apt-get update -q
$sudo apt-get install -y -q --no-install-recommends "${missing[@]}"
browser_deps
