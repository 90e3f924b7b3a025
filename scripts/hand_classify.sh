#!/usr/bin/env bash
# The twelve episodes of issue 45's hand classification: two of each failure class of the
# taxonomy (SPEC section 14), each pair from two methods, picked from the kept table 7 runs of
# scripts/residual_paper.sh (town-a, clean sensor, evaluated with the taxonomy). Each is driven
# again alone with `eval --record --trace` from a one-task suite (the built-in task, same id,
# traffic seed and timeout: the same episode), and `report --html` shows their replays. The
# class eval gives now is printed beside the kept one; the hand class goes in
# docs/benchmark.md, read off the page. Resumes: a finished episode is not run again.
#
#   scripts/hand_classify.sh            # -> runs/hand_classify/page.html, classes.tsv
set -euo pipefail
cd "$(dirname "$0")/.."
CD=${CD:-build/causaldrive}
CONFIG=${CONFIG:-configs/residual_paper.toml}
OUT=${OUT:-runs/residual_paper}
HAND=${HAND:-runs/hand_classify}
source scripts/paper_lib.sh

# class method seed suite task
PICKS=(
  "collision bc-oh 0 town-a-dense 2"
  "collision keyframe 1 town-a-regular 2"
  "stuck bc-oh 1 town-a-regular 17"
  "stuck bc-so 0 town-a-regular 13"
  "restart_stall bc-oh 1 town-a-dense 3"
  "restart_stall hd 2 town-a-regular 4"
  "stopped_free fca 1 town-a-regular 16"
  "stopped_free hd 1 town-a-regular 16"
  "blocked bc-oh 0 town-a-dense 1"
  "blocked dagger 0 town-a-regular 9"
  "slow bc-oh 1 town-a-dense 11"
  "slow dagger 1 town-a-regular 22"
)

mkdir -p "$HAND/suites"
dirs=()
printf 'kept_class\tmethod\tseed\tsuite\ttask\tclass_now\n' > "$HAND/classes.tsv.tmp"
for pick in "${PICKS[@]}"; do
  read -r class method seed suite task <<<"$pick"
  name=$suite-task$task
  file=$HAND/suites/$name.json
  python3 - "suites/$suite.json" "$task" "$file" <<'EOF'
import json, sys
src, task, out = sys.argv[1], int(sys.argv[2]), sys.argv[3]
suite = json.load(open(src))
suite["tasks"] = [t for t in suite["tasks"] if t["id"] == task]
suite["name"] += "-task%d" % task
assert len(suite["tasks"]) == 1, "no task %d in %s" % (task, src)
open(out + ".tmp", "w").write(json.dumps(suite, indent=1) + "\n")
EOF
  mv "$file.tmp" "$file"
  run=$OUT/train/seed$seed/$method
  restore_run "$run"
  dir=$HAND/$method-seed$seed-$name
  [[ -f $dir/results.json ]] || "$CD" eval --config "$CONFIG" --agent "$method" \
    --checkpoint "$run" --label "$method" --suite "$file" --trials 1 --workers 1 \
    --record --trace --quiet --out "$dir"
  now=$(python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["episodes"][0]["outcome"])' \
    "$dir/results.json")
  printf '%s\t%s\t%s\t%s\t%s\t%s\n' "$class" "$method" "$seed" "$suite" "$task" "$now" \
    >> "$HAND/classes.tsv.tmp"
  dirs+=("$dir")
done
mv "$HAND/classes.tsv.tmp" "$HAND/classes.tsv"
"$CD" report "${dirs[@]}" --metrics outcomes --html "$HAND/page.html" --episodes 0 \
  --replay-frames 400 --max-replays 12 > "$HAND/report.md"
column -t "$HAND/classes.tsv"
echo "page: $HAND/page.html"
