#!/usr/bin/env bash
# Keeps new weights (results/**/*.pt, each <= 5 MB) in git history without leaving them in the
# tree (results/WEIGHTS.md): one commit adds them, the next takes them out of the index again;
# scripts/restore_weights.sh brings them back in any later checkout.
#
#   scripts/keep_weights.sh results/residual_paper/train/seed0/residual [PATH...]
set -euo pipefail
cd "$(dirname "$0")/.."
mapfile -t files < <(find "$@" -name '*.pt' -size -5001k | sort)
(( ${#files[@]} > 0 )) || { echo "keep_weights: no .pt file under $*"; exit 0; }
git add -f -- "${files[@]}"
git commit -q -m "weights: ${#files[@]} file(s) under $* (kept in history; scripts/restore_weights.sh)"
git rm -q --cached -- "${files[@]}"
git commit -q -m "weights out of the tree again (results/WEIGHTS.md)"
echo "keep_weights: ${#files[@]} file(s) kept in $(git rev-parse --short HEAD~1)"
