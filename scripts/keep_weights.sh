#!/usr/bin/env bash
# Keeps new weights (results/**/*.pt, each <= 5 MB) in git history without leaving them in the
# tree (results/WEIGHTS.md): one commit adds them, the next takes them out of the index again
# and lists them in the manifest, results/weights.tsv, from which scripts/restore_weights.sh
# brings them back in any later checkout. Both commits hold those paths alone: whatever else is
# staged stays staged and uncommitted. A file over 5 MB is refused (nothing kept); a file the
# manifest lists with the same bytes is kept already (skipped).
#
#   scripts/keep_weights.sh results/residual_paper/train/seed0/residual [PATH...]
#   scripts/keep_weights.sh --manifest-only   # writes results/weights.tsv from history (not
#                                             # committed): every kept .pt of a live run
# A live run is a folder that still holds tracked files (its records) in HEAD and whose records
# were not deleted since its weights were kept; a deleted run's weights are left out.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd -P)
source "$root/scripts/weights_lib.sh"
fail() { echo "keep_weights: $*" >&2; exit 1; }
(( $# > 0 )) || fail "usage: scripts/keep_weights.sh PATH... | --manifest-only"

if [[ $1 == --manifest-only ]]; then
  cd "$root"
  [[ $(git rev-parse --is-shallow-repository) == false ]] ||
    fail "--manifest-only reads the whole history and this clone is shallow; run 'git fetch --unshallow' and retry"
  # live COMMIT FILE: FILE's folder has tracked files other than weights in HEAD, none of them
  # deleted since COMMIT (a folder deleted and made again holds another run).
  live() {
    local dir records deleted; dir=$(dirname "$2")
    records=$(git ls-tree --name-only HEAD -- "$dir/" | grep -v '\.pt$' || true)
    deleted=$(git log --no-renames --diff-filter=D --name-only --format= "$1..HEAD" -- "$dir/" |
              grep -v '\.pt$' || true)
    [[ -n $records && -z $deleted ]]
  }
  # --no-renames: a moved run's weights count as added where they are now.
  mapfile -t all < <(git log --no-renames --diff-filter=AM --name-only --format= -- 'results/*.pt' |
                     grep '\.pt$' | LC_ALL=C sort -u)
  lines=$(mktemp)
  trap 'rm -f "$lines"' EXIT
  dead=0
  for file in "${all[@]}"; do
    commit=$(git log --no-renames --diff-filter=AM --format=%H -n1 -- "$file")
    if live "$commit" "$file"; then weights_line "$commit" "$file"; else dead=$((dead + 1)); fi
  done > "$lines"
  weights_write /dev/null < "$lines"
  echo "keep_weights: $WEIGHTS_MANIFEST lists $(grep -vc '^#' "$WEIGHTS_MANIFEST") file(s) of live runs; $dead of deleted runs left out"
  exit 0
fi

mapfile -t paths < <(weights_relative "$root" "$@")
cd "$root"
for path in "${paths[@]}"; do
  [[ $path != .. && $path != ../* ]] || fail "$path is outside the repository"
  [[ -e $path ]] || fail "no $path"
done
# The manifest is rewritten from HEAD's: a change to it not committed would be lost.
if git cat-file -e "HEAD:$WEIGHTS_MANIFEST" 2>/dev/null; then
  git diff --quiet HEAD -- "$WEIGHTS_MANIFEST" ||
    fail "$WEIGHTS_MANIFEST has changes not committed; commit or drop them first"
else
  [[ ! -e $WEIGHTS_MANIFEST ]] || fail "$WEIGHTS_MANIFEST is not committed; commit or delete it first"
fi

files=()
while IFS= read -r file; do
  size=$(stat -c %s "$file")
  (( size <= WEIGHTS_MAX_BYTES )) ||
    fail "$file is $size bytes, over the $WEIGHTS_MAX_BYTES that git keeps (results/WEIGHTS.md); nothing kept"
  sha=$(weights_sha256 < "$file")
  [[ -f $WEIGHTS_MANIFEST ]] && awk -F'\t' -v f="$file" -v s="$sha" \
    '$1 == f && $2 == s { found = 1 } END { exit !found }' "$WEIGHTS_MANIFEST" && continue
  files+=("$file")
done < <(find "${paths[@]}" -name '*.pt' -type f | LC_ALL=C sort)
(( ${#files[@]} > 0 )) || { echo "keep_weights: no .pt file under $* that is not kept already"; exit 0; }

# Both commits are made from a private index (HEAD plus these paths), so the index of the
# checkout, and what is staged there, is not committed; it then takes the two paths as committed.
index=$(git rev-parse --absolute-git-dir)/keep_weights.index
trap 'rm -f "$index"' EXIT
GIT_INDEX_FILE=$index git read-tree HEAD
GIT_INDEX_FILE=$index git update-index --add -- "${files[@]}"
GIT_INDEX_FILE=$index git commit -q -m "weights: ${#files[@]} file(s) under $* (kept in history; $WEIGHTS_MANIFEST lists them)"
kept=$(git rev-parse HEAD)
old=/dev/null
[[ -f $WEIGHTS_MANIFEST ]] && old=$WEIGHTS_MANIFEST
for file in "${files[@]}"; do weights_line "$kept" "$file"; done | weights_write "$old"
GIT_INDEX_FILE=$index git rm -q --cached -- "${files[@]}"
GIT_INDEX_FILE=$index git add -- "$WEIGHTS_MANIFEST"
GIT_INDEX_FILE=$index git commit -q -m "weights out of the tree again, listed in $WEIGHTS_MANIFEST (results/WEIGHTS.md)"
git reset -q -- "$WEIGHTS_MANIFEST" "${files[@]}"
echo "keep_weights: ${#files[@]} file(s) kept in $(git rev-parse --short "$kept"), listed in $WEIGHTS_MANIFEST"
