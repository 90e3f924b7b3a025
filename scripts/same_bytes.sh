#!/usr/bin/env bash
# Do two builds give the same outputs? Runs a small chain (collect 6 noisy episodes; train
# bc-oh, dim, rip, cim, cim-mlp --vae; eval expert, cs, bc-oh, dim, cim on the quickstart suite)
# with each binary and compares every output file. JSON files are compared without their
# timing, device and path keys (scripts/output_digest.py; IGNORE_SETTINGS=1 also leaves out the
# records' settings sections). A refactoring should print "same bytes".
#
#   scripts/same_bytes.sh OLD_BINARY NEW_BINARY [WORK_DIR]
set -euo pipefail
if [[ $# -lt 2 ]]; then
  echo "usage: $0 OLD_BINARY NEW_BINARY [WORK_DIR]" >&2
  exit 2
fi
old=$(readlink -f "$1"); new=$(readlink -f "$2")
work=${3:-$(mktemp -d /tmp/causaldrive-same-bytes-XXXXXX)}
here=$(cd "$(dirname "$0")" && pwd)

chain() {  # BINARY OUT
  local bin=$1 out=$2
  rm -rf "$out"; mkdir -p "$out"
  cat > "$out/cfg.toml" <<TOML
[world]
town = "town-a"
traffic = "regular"
warmup_s = 10
[collect]
episodes = 6
workers = 2
seed = 7
min_route_m = 150
max_route_m = 300
out = "$out/data"
[collect.noise]
enabled = true
[train]
epochs = 2
batch_size = 32
max_samples = 1500
threads = 2
[vae]
latents = 16
epochs = 1
max_frames = 800
[cim]
epochs = 3
[dim]
ensemble = 2
[eval]
suite = "quickstart"
workers = 2
TOML
  local c="$out/cfg.toml"
  "$bin" collect --config "$c" > "$out/log" 2>&1
  for m in bc-oh dim rip cim; do
    "$bin" train --config "$c" --method $m --data "$out/data" --out "$out/train/$m" >> "$out/log" 2>&1
  done
  "$bin" train --config "$c" --method cim-mlp --vae "$out/train/cim" --data "$out/data" \
    --out "$out/train/cim-mlp" >> "$out/log" 2>&1
  for a in expert cs bc-oh dim cim; do
    local ck=()
    [[ -d "$out/train/$a" ]] && ck=(--checkpoint "$out/train/$a")
    "$bin" eval --config "$c" --agent $a "${ck[@]}" --out "$out/eval/$a" --quiet >> "$out/log" 2>&1
  done
}

echo "old: $old -> $work/old"; chain "$old" "$work/old"
echo "new: $new -> $work/new"; chain "$new" "$work/new"
python3 "$here/output_digest.py" "$work/old" > "$work/old.digest"
python3 "$here/output_digest.py" "$work/new" > "$work/new.digest"
if diff "$work/old.digest" "$work/new.digest"; then
  echo "same bytes ($(wc -l < "$work/new.digest") files)"
else
  echo "outputs differ (above)"
  exit 1
fi
