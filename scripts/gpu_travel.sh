#!/usr/bin/env bash
# What a call to a lent GPU machine carries: the working tree (tracked files and untracked ones git
# does not ignore) and the ignored paths the call names, 64 MiB in all (docs/gpu.md). The tracked
# tree alone is ~61 MB, nearly all of it results/ (kept evaluations), which neither the build nor
# training reads, so a call that carries data moves results/ out of the checkout first.
#
#   scripts/gpu_travel.sh size [CARRY...]   # the bytes that would travel, against 64 MiB
#   scripts/gpu_travel.sh aside             # moves results/ to ../.causaldrive-results-aside
#   scripts/gpu_travel.sh back              # moves it back (refuses if results/ exists again)
#
# `aside` refuses while a job of this checkout runs (scripts/verdicts.sh or the like read and
# write results/); `back` after every call, before anything else runs.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd -P)
cd "$root"
aside="$root/../.causaldrive-results-aside"
limit=$((64 * 1024 * 1024))
fail() { echo "gpu_travel: $*" >&2; exit 1; }

size_of() {  # the bytes of the existing files among git's list (NUL-separated on stdin)
  local total=0 n
  while IFS= read -r -d '' f; do
    [[ -f $f && ! -L $f ]] || continue
    n=$(stat -c %s "$f")
    total=$((total + n))
  done
  echo "$total"
}

case ${1:-} in
  size)
    shift
    tree=$(git ls-files -z --cached --others --exclude-standard | size_of)
    carried=0
    for c in "$@"; do
      [[ -e $c ]] || fail "$c: no such path to carry"
      carried=$((carried + $(du -sb "$c" | cut -f1)))
    done
    total=$((tree + carried))
    awk -v t="$tree" -v c="$carried" -v l="$limit" 'BEGIN {
      printf "tree %.1f MB + carried %.1f MB = %.1f MB of %.1f MB (64 MiB): %s\n", t / 1e6, c / 1e6,
        (t + c) / 1e6, l / 1e6, (t + c <= l) ? "fits" : "too large: scripts/gpu_travel.sh aside" }'
    ((total <= limit))
    ;;
  aside)
    [[ -d results ]] || fail "results/ is not here (aside already? scripts/gpu_travel.sh back)"
    [[ ! -e $aside ]] || fail "$aside exists: move it back first (scripts/gpu_travel.sh back)"
    # This script and the shells that called it are not jobs.
    ancestors=" " p=$$
    while [[ -n $p && $p != 0 ]]; do
      ancestors+="$p "
      p=$(awk '/^PPid:/ { print $2 }' "/proc/$p/status" 2>/dev/null)
    done
    for pid in $(pgrep -f 'causaldrive|scripts/.*\.(sh|py)' || true); do
      [[ $ancestors != *" $pid "* && $(readlink "/proc/$pid/cwd" 2>/dev/null) == "$root"* ]] ||
        continue
      fail "process $pid ($(tr '\0' ' ' <"/proc/$pid/cmdline" | cut -c1-60)) runs in this checkout and may read results/: stop it first"
    done
    mv results "$aside"
    echo "results/ moved to $aside; after the call: scripts/gpu_travel.sh back"
    ;;
  back)
    [[ -d $aside ]] || fail "nothing aside ($aside)"
    [[ ! -e results ]] || fail "results/ exists again: merge $aside into it by hand"
    mv "$aside" results
    echo "results/ back"
    ;;
  *)
    fail "usage: scripts/gpu_travel.sh size [CARRY...] | aside | back"
    ;;
esac
