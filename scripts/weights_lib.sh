# Shared by scripts/keep_weights.sh and scripts/restore_weights.sh (source it from the repository
# root): the manifest of the kept weights, results/weights.tsv (results/WEIGHTS.md). One line per
# weights file of a live kept run, tab-separated and sorted by path under one header line:
#   path  sha256  size (bytes)  blob (git object id)  commit (the one that holds the bytes)
# The commit is what a shallow clone fetches to get the bytes (`git fetch --depth 1 origin C`).

WEIGHTS_MANIFEST=results/weights.tsv
WEIGHTS_HEADER=$'# path\tsha256\tsize\tblob\tcommit'
WEIGHTS_MAX_BYTES=5000000  # git keeps no file larger (as paper_lib.sh's KEEP_MAX_MB)

# weights_sha256: the sha256 of standard input, hex.
weights_sha256() { sha256sum | cut -c1-64; }

# weights_relative ROOT PATH...: each PATH (relative to the caller's folder or absolute) relative
# to ROOT, one a line; "." for ROOT itself. Resolved before a script cds to the root, so a path
# given from anywhere names the same file.
weights_relative() {
  local root=$1 path; shift
  for path; do realpath -m --relative-to="$root" -- "$path"; done
}

# weights_line COMMIT PATH: PATH's manifest line, from its bytes in COMMIT.
weights_line() {
  local blob sha
  blob=$(git rev-parse "$1:$2")
  sha=$(git cat-file blob "$blob" | weights_sha256)
  printf '%s\t%s\t%s\t%s\t%s\n' "$2" "$sha" "$(git cat-file -s "$blob")" "$blob" "$1"
}

# weights_write OLD: writes the manifest, atomically: the lines on standard input, and OLD's
# lines (a manifest, or /dev/null) for the paths that standard input does not name.
weights_write() {
  local tmp=$WEIGHTS_MANIFEST.tmp
  {
    echo "$WEIGHTS_HEADER"
    awk -F'\t' 'NR == FNR { if ($0 !~ /^#/ && NF) { line[$1] = $0 }; next }
                $0 !~ /^#/ && NF && !($1 in line) { print }
                END { for (p in line) print line[p] }' - "$1" | LC_ALL=C sort -t$'\t' -k1,1
  } > "$tmp" && mv "$tmp" "$WEIGHTS_MANIFEST"
}
