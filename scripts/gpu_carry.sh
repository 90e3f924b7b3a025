#!/usr/bin/env bash
# Prepares .gpu/ (git ignores it) for a GPU machine that cannot fetch anything: the Debian
# packages causaldrive builds with that such a machine may lack (unpacked by scripts/gpu_check.sh
# into a private prefix, never into /), and a small data folder to train on.
#
#   scripts/gpu_carry.sh [DATA] [EPISODES]
#
# DATA: a `causaldrive collect` folder (default: collect EPISODES quickstart episodes, 8 by
# default, into .gpu/data with build/causaldrive). On your own GPU machine with the packages
# installed, nothing needs carrying: run scripts/gpu_check.sh alone.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
cd "$root"
data="${1:-}"
episodes="${2:-8}"
mkdir -p .gpu/debs
# Header libraries and GoogleTest (the rest, HDF5, Eigen, Boost, CLI11 and nlohmann-json, the
# machine has; SUMO and MuJoCo are left out of that build).
(cd .gpu/debs && apt-get download libtomlplusplus-dev libtomlplusplus3 libstb-dev libgtest-dev \
  >/dev/null 2>&1)
if [[ -n "$data" ]]; then
  rm -rf .gpu/data
  mkdir -p .gpu/data
  cp "$data"/*.h5 "$data"/*.json .gpu/data/ 2>/dev/null || cp -r "$data"/. .gpu/data/
elif [[ ! -d .gpu/data ]]; then
  build/causaldrive collect --episodes "$episodes" --out .gpu/data
fi
du -sh .gpu/debs .gpu/data
