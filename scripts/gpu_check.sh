#!/usr/bin/env bash
# The GPU check (SPEC section 11, docs/gpu.md): on a machine with an NVIDIA GPU and PyTorch, in one
# command, build causaldrive against PyTorch's CUDA libtorch, run the unit tests with `auto`
# resolving to CUDA, train bc-oh on a data folder on CUDA and on the CPU, time the training
# step against its PyTorch-Python peer (scripts/gpu_peer.py), and print one JSON line with every
# figure and the time of each step.
#
#   scripts/gpu_check.sh [DATA]
#
# DATA: a `causaldrive collect` folder (default: .gpu/data, else runs/quickstart/data); without
# one the training step is skipped. Environment:
#   JOBS      build jobs (default: all cores)
#   BUILD     build folder (default: build-gpu)
#   CD_DEBS   folder of Debian packages to unpack into a private prefix when the machine lacks
#             them (default .gpu/debs; scripts/gpu_carry.sh fills it)
#   SUMO      ON | OFF | auto (default auto: ON when SUMO's CMake config is installed)
#   OUT       where the logs go (default: a temporary folder); the JSON is also OUT/gpu_check.json
exec python3 "$(dirname "$0")/gpu_check.py" "$@"
