#!/usr/bin/env bash
# What a call to a lent GPU machine carries: the working tree (tracked files and untracked ones git
# does not ignore) and the ignored paths the call names, 64 MiB in all (docs/gpu.md). The tracked
# tree alone is ~61 MB, nearly all of it results/ (kept evaluations), which neither the build nor
# training reads, so a call that carries data moves results/ out of the checkout first.
#
#   scripts/gpu_travel.sh size [CARRY...]   # the bytes that would travel, against 64 MiB
#   scripts/gpu_travel.sh aside             # moves results/ to ../.causaldrive-results-aside
#   scripts/gpu_travel.sh back              # moves it back (refuses if results/ exists again)
#   scripts/gpu_travel.sh split DIR DEST [MB]
#       # a data folder too large for one call (the camera's, ~290 MB) as hard links in
#       # DEST/part1, part2, ... of at most MB each (default 55): carry one part a call on the
#       # same warm machine (what a call leaves there stays), then name DEST as the run's DATA
#       # (scripts/gpu_runs.py joins the parts)
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
  split)
    [[ $# -ge 3 && $# -le 4 ]] || fail "usage: scripts/gpu_travel.sh split DIR DEST [MB]"
    dir=$2 dest=$3 mb=${4:-55}
    [[ $mb =~ ^[1-9][0-9]*$ ]] || fail "MB: expected a whole number of megabytes, got '$mb'"
    [[ -f $dir/collect.json ]] || fail "$dir: not a collect folder (no collect.json)"
    [[ ! -e $dest ]] || fail "$dest exists: remove it first"
    max=$((mb * 1000000)) part=1 used=0
    mkdir -p "$dest.tmp/part1"
    ln "$dir/collect.json" "$dest.tmp/part1/"
    used=$(stat -c %s "$dir/collect.json")
    while IFS= read -r f; do
      n=$(stat -c %s "$f")
      ((n <= max)) || { rm -rf "$dest.tmp"; fail "$f: $n bytes, over the part's $mb MB"; }
      if ((used + n > max)); then
        part=$((part + 1)) used=0
        mkdir "$dest.tmp/part$part"
      fi
      ln "$f" "$dest.tmp/part$part/"
      used=$((used + n))
    done < <(find "$dir" -maxdepth 1 -type f ! -name collect.json ! -name causaldrive.lock | sort)
    mv "$dest.tmp" "$dest"
    for d in "$dest"/part*; do echo "$d $(du -sb "$d" | cut -f1) bytes"; done
    ;;
  *)
    fail "usage: scripts/gpu_travel.sh size [CARRY...] | aside | back | split DIR DEST [MB]"
    ;;
esac
