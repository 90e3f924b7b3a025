#!/usr/bin/env bash
# Restores the kept weights (results/**/*.pt) under each PATH from git history into the working
# tree, where .gitignore keeps them out of the tree that travels (results/WEIGHTS.md). A file
# present is left as it is; each missing one is taken from the last commit that added or changed
# it. Prints how many it restored.
#
#   scripts/restore_weights.sh results/residual_paper/train [PATH...]
set -euo pipefail
cd "$(dirname "$0")/.."
(( $# > 0 )) || set -- results
restored=0
while IFS= read -r file; do
  [[ -z $file || -f $file ]] && continue
  sha=$(git log --diff-filter=AM --format=%H -n1 -- "$file")
  [[ -n $sha ]] || continue
  mkdir -p "$(dirname "$file")"
  git show "$sha:$file" > "$file.tmp" && mv "$file.tmp" "$file"
  restored=$((restored + 1))
done < <(git log --diff-filter=AM --name-only --format= -- "$@" | grep '\.pt$' | sort -u)
echo "restore_weights: $restored file(s) restored under $*"
