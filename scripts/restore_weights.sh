#!/usr/bin/env bash
# Restores the kept weights under each PATH (default: results) into the working tree, where
# .gitignore keeps them out of the tree that travels (results/WEIGHTS.md). It reads only the
# manifest, results/weights.tsv: a file it does not list (a deleted run's) never comes back.
# For each listed file under PATH whose folder exists (a run deleted from the tree is skipped):
# one present with the listed sha256 is left alone; one present with another is an error, never
# overwritten; a missing one is written from its git blob, through a temporary file beside it,
# and checked. A shallow clone lacks the blobs: it fetches them from origin once, all at once,
# by id (their bytes alone), and if origin refuses, once by their commits (--depth 1: each
# commit's whole tree); a partial clone (--filter=blob:none) fetches them by itself. Any failure
# is one line on stderr and exit 1, naming the file and the fix; else one line says how many
# files it restored.
#
#   scripts/restore_weights.sh results/residual_paper/train [PATH...]
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd -P)
source "$root/scripts/weights_lib.sh"
if (( $# > 0 )); then mapfile -t paths < <(weights_relative "$root" "$@"); else paths=(results); fi
cd "$root"

fail() { echo "restore_weights: $*" >&2; exit 1; }
tmp=""
trap 'rm -f -- "$tmp"' EXIT  # a failed or interrupted read leaves no temporary

# Whether this is a git checkout of its own (a tarball is not, even unpacked inside another one).
git_root=$(git rev-parse --show-toplevel 2>/dev/null || true)
[[ -n $git_root && $(cd "$git_root" && pwd -P) == "$root" ]] && checkout=1 || checkout=0

# The manifest's files under PATH whose folder exists: the present ones are checked, the missing
# ones listed.
files=() shas=() sizes=() blobs=() commits=()
present=0
if [[ -f $WEIGHTS_MANIFEST ]]; then
  while IFS=$'\t' read -r file sha size blob commit; do
    [[ -z $file || $file == \#* ]] && continue
    under=0
    for path in "${paths[@]}"; do
      [[ $path == . || $file == "$path" || $file == "$path"/* ]] && under=1 && break
    done
    [[ $under == 1 && -d $(dirname "$file") ]] || continue  # not asked for, or a deleted run
    if [[ -e $file ]]; then
      got=$(weights_sha256 < "$file")
      [[ $got == "$sha" ]] || fail "$file: not the kept bytes (sha256 ${got:0:12}, $WEIGHTS_MANIFEST has ${sha:0:12}); left as it is: keep it with scripts/keep_weights.sh $(dirname "$file"), or delete it to restore the kept one"
      present=$((present + 1))
      continue
    fi
    files+=("$file") shas+=("$sha") sizes+=("$size") blobs+=("$blob") commits+=("$commit")
  done < "$WEIGHTS_MANIFEST"
fi

# lacking: the listed blobs this clone does not hold.
lacking() {
  printf '%s\n' "${blobs[@]}" | git cat-file --batch-check | awk '$2 == "missing" { print $1 }'
}
shallow=false
if (( ${#files[@]} > 0 )); then
  (( checkout )) || fail "${files[0]}: this is not a git checkout (a tarball?), so its kept bytes (commit ${commits[0]:0:7}) cannot be read; clone the repository (git clone) and retry"
  shallow=$(git rev-parse --is-shallow-repository)
fi
if [[ $shallow == true ]]; then
  mapfile -t missing < <(lacking)
  if (( ${#missing[@]} > 0 )); then
    GIT_TERMINAL_PROMPT=0 git fetch -q origin "${missing[@]}" >/dev/null 2>&1 || true
    mapfile -t missing < <(lacking)
  fi
  if (( ${#missing[@]} > 0 )); then
    declare -A commit_of=() wanted=()
    for i in "${!blobs[@]}"; do commit_of[${blobs[i]}]=${commits[i]}; done
    for blob in "${missing[@]}"; do wanted[${commit_of[$blob]}]=1; done
    GIT_TERMINAL_PROMPT=0 git fetch -q --depth 1 origin "${!wanted[@]}" >/dev/null 2>&1 || true
  fi
fi

for i in "${!files[@]}"; do
  file=${files[i]} blob=${blobs[i]} commit=${commits[i]}
  tmp=$(mktemp --suffix=.tmp "$file.XXXXXX")
  if ! git cat-file blob "$blob" > "$tmp" 2>/dev/null; then
    [[ $shallow == true ]] &&
      fail "$file: its bytes (commit ${commit:0:7}) are not in this clone (shallow); run 'git fetch --unshallow' and retry"
    fail "$file: its bytes (commit ${commit:0:7}) are not in this clone and origin did not send them; run 'git fetch origin' with origin reachable and retry"
  fi
  got=$(weights_sha256 < "$tmp")
  [[ $got == "${shas[i]}" && $(stat -c %s "$tmp") == "${sizes[i]}" ]] ||
    fail "$file: blob ${blob:0:12} does not match $WEIGHTS_MANIFEST (sha256 ${got:0:12}, listed ${shas[i]:0:12}); not restored"
  mv -- "$tmp" "$file"
  tmp=""
done
echo "restore_weights: ${#files[@]} file(s) restored, $present already present under ${*:-results}"
