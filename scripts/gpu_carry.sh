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
# What the build needs beyond a compiler, CMake and PyTorch: HDF5 (with the libraries it links:
# szip, curl and curl's own), TOML++, CLI11, nlohmann-json, Eigen, stb and GoogleTest. SUMO and
# MuJoCo are left out of that build. gpu_check.py keeps of the runtime libraries only those the
# machine lacks.
(cd .gpu/debs && apt-get download libhdf5-dev libhdf5-103-1 libhdf5-cpp-103-1 libhdf5-hl-100 \
  libhdf5-hl-cpp-100 libaec-dev libaec0 libsz2 libcurl4 libbrotli1 libffi8 libgmp10 libgnutls30 \
  libgssapi-krb5-2 libhogweed6 libidn2-0 libk5crypto3 libkrb5-3 libkrb5support0 libldap-2.5-0 \
  libnettle8 libnghttp2-14 libp11-kit0 libpsl5 librtmp1 libsasl2-2 libssh2-1 libssl3 \
  libtasn1-6 libunistring2 libzstd1 libcom-err2 libkeyutils1 zlib1g zlib1g-dev \
  libtomlplusplus-dev libtomlplusplus3 libcli11-dev nlohmann-json3-dev libeigen3-dev \
  libstb-dev libstb0 libgtest-dev >/dev/null)
if [[ -n "$data" ]]; then
  rm -rf .gpu/data
  mkdir -p .gpu/data
  cp "$data"/*.h5 "$data"/*.json .gpu/data/ 2>/dev/null || cp -r "$data"/. .gpu/data/
elif [[ ! -d .gpu/data ]]; then
  build/causaldrive collect --episodes "$episodes" --out .gpu/data
fi
du -sh .gpu/debs .gpu/data
