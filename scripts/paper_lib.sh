# Shared by the reproduction scripts (scripts/cim_paper.sh, scripts/residual_paper.sh): the test
# suites at a chosen size and the evaluation loop. Source it after setting
#   CD OUT CONFIG SEEDS TASKS TRIALS WORKERS
# Every step resumes: eval skips the episodes its output folder already holds.

[[ -x $CD ]] || { echo "error: $CD not found; run 'make build' first (or set CD)" >&2; exit 1; }

# The suite file (or built-in name) of a test suite at $TASKS tasks.
suite_of() {
  local name=$1
  if [[ $TASKS == 25 ]]; then echo "$name"; return; fi
  local file=$OUT/suites/$name-$TASKS.json
  if [[ ! -f $file ]]; then
    mkdir -p "$OUT/suites"
    local town=${name%-*} kind=${name##*-} seed
    seed=$(( 5000 + $(cksum <<<"$name" | cut -d' ' -f1) % 1000 ))
    if [[ $kind == stopgo ]]; then
      "$CD" suite --name "$name-$TASKS" --town "$town" --traffic regular --tasks "$TASKS" \
        --trials "$TRIALS" --seed "$seed" --scenarios red_light,leader --min-route 120 \
        --max-route 300 --out "$file" >&2
    else
      "$CD" suite --name "$name-$TASKS" --town "$town" --traffic "$kind" --tasks "$TASKS" \
        --trials "$TRIALS" --seed "$seed" --out "$file" >&2
    fi
  fi
  echo "$file"
}

# eval_agents TABLE METRICS SENSOR SUITES AGENTS...: every agent x seed x suite (SENSOR clean or
# shifted), then `report --metrics METRICS` over them into $OUT/TABLE.md and .csv. An agent is
# a method name, "cs" (nothing trained: one run), or LABEL=METHOD for a run trained under
# another label (an ablation: $OUT/train/seedS/LABEL holds a METHOD run); "NAME-fewshot" runs
# are the NAME method.
eval_agents() {
  local table=$1 metrics=$2 sensor=$3 suites=$4; shift 4
  local dirs=() tag=""
  [[ $sensor == clean ]] || tag="-$sensor"
  for agent in "$@"; do
    local label=${agent%%=*} kind=${agent#*=}
    if [[ $label == *-fewshot && $agent != *=* ]]; then kind=${label%-fewshot}; fi
    for name in $suites; do
      local suite; suite=$(suite_of "$name")
      if [[ $kind == cs ]]; then
        local dir=$OUT/eval/cs/$name$tag
        "$CD" eval --config "$CONFIG" --agent cs --suite "$suite" --trials "$TRIALS" \
          --workers "$WORKERS" --sensor "$sensor" --quiet --out "$dir"
        dirs+=("$dir")
        continue
      fi
      for s in $SEEDS; do
        local dir=$OUT/eval/$label/seed$s/$name$tag
        "$CD" eval --config "$CONFIG" --agent "$kind" --checkpoint "$OUT/train/seed$s/$label" \
          --label "$label" --suite "$suite" --trials "$TRIALS" --workers "$WORKERS" \
          --sensor "$sensor" --quiet --out "$dir"
        dirs+=("$dir")
      done
    done
  done
  "$CD" report "${dirs[@]}" --metrics "$metrics" --markdown "$OUT/$table.md" --csv "$OUT/$table.csv"
}
