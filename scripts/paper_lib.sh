# Shared by the reproduction scripts (scripts/cim_paper.sh, scripts/residual_paper.sh,
# scripts/mujoco_paper.sh): the kept results, the test suites at a chosen size and the evaluation
# loop. Source it after setting
#   CD OUT CONFIG SEEDS TASKS TRIALS WORKERS
# Every step resumes: eval skips the episodes its output folder already holds.
#
# Kept results. $OUT (runs/..., ignored by git) holds data, checkpoints and evaluations, and is
# lost with the checkout. Every finished evaluation's results.json, probe report and table, and
# for the scripts that train through kept_train every finished run, is also copied to $KEEP
# (default results/<name of $OUT>, committed), at the same path relative to $OUT; an evaluation
# holding an infrastructure failure is not, nor a table over one. A result found
# in $KEEP is used as it is: its evaluation is not run again and its checkpoint is not needed, so
# a table resumes in a fresh checkout from what earlier sessions measured. Delete a kept file (or the folder) to measure it again, e.g. after a code change.

shopt -s inherit_errexit  # a failing command in $(...) fails the script, not only the subshell
[[ -x $CD ]] || { echo "error: $CD not found; run 'make build' first (or set CD)" >&2; exit 1; }
KEEP=${KEEP:-results/$(basename "$OUT")}

# kept_of PATH: where $KEEP keeps $OUT/REL (PATH): $KEEP/REL.
kept_of() { echo "$KEEP/${1#"$OUT"/}"; }

# keep_file PATH: copies $OUT/REL (PATH) to $KEEP/REL, atomically.
keep_file() {
  local kept; kept=$(kept_of "$1")
  mkdir -p "$(dirname "$kept")"
  cp "$1" "$kept.tmp" && mv "$kept.tmp" "$kept"
}

# kept_json FILE CMD...: CMD's standard output as FILE (a JSON report), kept in $KEEP; a kept
# FILE is not measured again, and FILE appears whole or not at all. A FILE without its kept copy
# (the kept one deleted to measure it again, or left by another binary) is measured again.
kept_json() {
  local file=$1; shift
  [[ -f $(kept_of "$file") ]] && return
  mkdir -p "$(dirname "$file")"
  "$@" > "$file.tmp" || { rm -f "$file.tmp"; echo "error: no $file (its command failed)" >&2; return 1; }
  mv "$file.tmp" "$file"
  keep_file "$file"
}

# restore_run DIR: copies the run kept for DIR back into DIR (whole or not at all), unless DIR
# exists already. Its weights come back from git history first (scripts/restore_weights.sh,
# results/WEIGHTS.md); when they cannot (a shallow clone, a tarball), it fails with restore's
# one line on stderr rather than reuse a run without its weights.
restore_run() {
  local dir=$1 kept; kept=$(kept_of "$1")
  [[ -d $kept && ! -d $dir ]] || return 0
  "$(dirname "${BASH_SOURCE[0]}")/restore_weights.sh" "$kept" >/dev/null || return
  mkdir -p "$(dirname "$dir")"
  rm -rf "$dir.tmp"
  mkdir "$dir.tmp"
  cp "$kept"/* "$dir.tmp"/ && mv "$dir.tmp" "$dir"
}

# kept_train DIR ARGS...: `causaldrive train ARGS --out DIR`, the finished run kept in $KEEP
# (weights and records; not cim's Granger series series.csv, 40 MB, which only `causaldrive
# granger` reads, nor the policy family's resume state, model.pt and optimizer.pt: agents load
# best.pt, nor the folder's lock file). A run holding a file over KEEP_MAX_MB (default 5) is not kept, since git holds no
# file that large: it stays in DIR and a fresh checkout trains it again (its checkpoint.json and
# metrics.jsonl are kept in KEPT.record, as a record only). A kept run is used as
# it is, like a kept evaluation: it is copied back into DIR and not trained again, so a fresh
# checkout evaluates the same weights (retraining on another machine gives other floats:
# libtorch picks its kernels by CPU). Identical files (the VAE that cim-mlp and the few-shot
# runs copy) are one object in git. The kept folder
# appears whole or not at all (written as KEPT.tmp, then renamed).
kept_train() {
  local dir=$1; shift
  local kept file; kept=$(kept_of "$dir")
  if [[ -d $kept ]]; then
    restore_run "$dir" || return  # no weights: the step stops (not trained again either)
    return 0
  fi
  # Finished with weights over the limit, here or elsewhere (scripts/gpu_import.py): its record
  # kept, its weights in DIR. (A folder imported from a lent machine has no resume state, so
  # `train` could not even resume it.)
  [[ -d $kept.record && -f $dir/best.pt ]] && return 0
  "$CD" train "$@" --out "$dir"
  local files=() max_mb=${KEEP_MAX_MB:-5} over=""
  for file in "$dir"/*; do
    [[ -f $file ]] || continue
    case $(basename "$file") in series.csv | model.pt | optimizer.pt | causaldrive.lock) continue ;; esac
    if (( $(stat -c %s "$file") > max_mb * 1000000 )); then
      over+=" $(basename "$file")"
      continue
    fi
    files+=("$file")
  done
  if [[ -n $over ]]; then
    # The files under the limit (its record) are kept beside, as KEPT.record: never restored,
    # so a fresh checkout trains it again.
    echo "$dir: not kept (${over# } over $max_mb MB); its record is kept in $kept.record" >&2
    rm -rf "$kept.record.tmp"
    mkdir -p "$kept.record.tmp"
    [[ ${#files[@]} == 0 ]] || cp "${files[@]}" "$kept.record.tmp/"
    rm -rf "$kept.record"
    mv "$kept.record.tmp" "$kept.record"
    return 0
  fi
  rm -rf "$kept.tmp"
  mkdir -p "$kept.tmp"
  cp "${files[@]}" "$kept.tmp/"
  mv "$kept.tmp" "$kept"
  if compgen -G "$kept/*.pt" >/dev/null; then
    echo "$kept: kept; git ignores its weights: scripts/keep_weights.sh $kept keeps them in history (results/WEIGHTS.md)" >&2
  fi
}

# has_failures DIR: whether DIR's results.json holds an episode that failed outside the agent
# (an infrastructure failure: a rerun of its evaluation retries it).
has_failures() { grep -q '"infrastructure_failure"' "$1/results.json" 2>/dev/null; }

# kept_eval DIR ARGS...: sets KEPT to the folder whose results.json the tables read: $KEEP's copy
# of DIR when one is kept, else DIR after `causaldrive eval ARGS --out DIR` (kept when no episode
# ended in an infrastructure failure, which a rerun would retry).
kept_eval() {
  local dir=$1; shift
  KEPT=$(kept_of "$dir")
  [[ -f $KEPT/results.json ]] && return
  "$CD" eval "$@" --out "$dir"
  if has_failures "$dir"; then
    KEPT=$dir
  else
    keep_file "$dir/results.json"
  fi
}

# kept_report TABLE METRICS DIRS...: `causaldrive report` over DIRS into $OUT/TABLE.md and .csv,
# both kept, unless a run among DIRS holds an infrastructure failure (kept_eval did not keep it:
# a rerun retries its episodes). Then the table is written in $OUT only, to look at, the kept
# one stays as it was, and the step fails naming those runs, so that no kept table averages a
# partial run in.
kept_report() {
  local table=$1 metrics=$2 dir failed=(); shift 2
  "$CD" report "$@" --metrics "$metrics" --markdown "$OUT/$table.md" --csv "$OUT/$table.csv"
  for dir in "$@"; do
    has_failures "$dir" && failed+=("$dir")
  done
  if [[ ${#failed[@]} != 0 ]]; then
    echo "error: $OUT/$table.md not kept: ${#failed[@]} run(s) hold episodes that failed" \
      "outside the agent (run the step again to retry them): ${failed[*]}" >&2
    return 1
  fi
  keep_file "$OUT/$table.md"
  keep_file "$OUT/$table.csv"
}

# mode_config MODE: a config holding only `[ego] lateral = MODE` (route or free), as
# $OUT/configs/expert-MODE.toml; the quickstart settings otherwise (the expert's runs).
mode_config() {  # MODE -> a config
  local file=$OUT/configs/expert-$1.toml
  mkdir -p "$OUT/configs"
  printf '[ego]\nlateral = "%s"\n' "$1" > "$file.tmp" && mv "$file.tmp" "$file"
  echo "$file"
}

# The suite file (or built-in name) of a test suite at $TASKS tasks, drawn with $CONFIG's world
# settings: a route-mode config (ego.lateral = "route") draws no route that needs a lane change,
# which its ego could not drive (the default, "free", draws them: on town-c three in four).
suite_of() {
  local name=$1
  if [[ $TASKS == 25 ]]; then echo "$name"; return; fi
  local file=$OUT/suites/$name-$TASKS.json
  if [[ ! -f $file ]]; then
    mkdir -p "$OUT/suites"
    local town=${name%-*} kind=${name##*-} seed
    seed=$(( 5000 + $(cksum <<<"$name" | cut -d' ' -f1) % 1000 ))
    if [[ $kind == stopgo ]]; then
      "$CD" suite ${CONFIG:+--config "$CONFIG"} --name "$name-$TASKS" --town "$town" \
        --traffic regular --tasks "$TASKS" \
        --trials "$TRIALS" --seed "$seed" --scenarios red_light leader --min-route 120 \
        --max-route 300 --out "$file" >&2
    else
      "$CD" suite ${CONFIG:+--config "$CONFIG"} --name "$name-$TASKS" --town "$town" \
        --traffic "$kind" --tasks "$TASKS" \
        --trials "$TRIALS" --seed "$seed" --out "$file" >&2
    fi
  fi
  echo "$file"
}

# eval_agents TABLE METRICS SENSOR SUITES AGENTS...: every agent x seed x suite (SENSOR clean or
# shifted), then `report --metrics METRICS` over them into $OUT/TABLE.md and .csv (kept). An agent is
# a method name, "cs" (nothing trained: one run), or LABEL=METHOD for a run trained under
# another label (an ablation: $OUT/train/seedS/LABEL holds a METHOD run); "NAME-fewshot" runs
# are the NAME method. With CIM_PATH=LABEL set, cim agents steer along the path of the dim/rip
# run $OUT/train/seedS/LABEL of their own seed (eval --cim-path; a free-steering ego).
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
        kept_eval "$OUT/eval/cs/$name$tag" --config "$CONFIG" --agent cs --suite "$suite" \
          --trials "$TRIALS" --workers "$WORKERS" --sensor "$sensor" --quiet
        dirs+=("$KEPT")
        continue
      fi
      for s in $SEEDS; do
        local path=()
        restore_run "$OUT/train/seed$s/$label" || return
        if [[ $kind == cim* && -n ${CIM_PATH:-} ]]; then
          restore_run "$OUT/train/seed$s/$CIM_PATH" || return
          path=(--cim-path "$OUT/train/seed$s/$CIM_PATH")
        fi
        kept_eval "$OUT/eval/$label/seed$s/$name$tag" --config "$CONFIG" --agent "$kind" \
          --checkpoint "$OUT/train/seed$s/$label" --label "$label" --suite "$suite" \
          --trials "$TRIALS" --workers "$WORKERS" --sensor "$sensor" --quiet "${path[@]}"
        dirs+=("$KEPT")
      done
    done
  done
  kept_report "$table" "$metrics" "${dirs[@]}"
}

# run_steps "STEP..." ARGS...: the script's command line. Runs each step named in ARGS, in
# order, with the script's run_step function. Every name is checked against the STEP list
# before the first one runs, so a typo fails at once rather than after hours of compute.
# Without a step, prints the script's header comment (its usage) and exits 2.
run_steps() {
  local known=" $1 " step; shift
  if [[ $# == 0 ]]; then
    awk 'NR > 1 && /^#/ { sub(/^# ?/, ""); print; next } NR > 1 { exit }' "$0"
    exit 2
  fi
  for step in "$@"; do
    [[ $known == *" $step "* ]] ||
      { echo "error: unknown step '$step' (steps:${known% })" >&2; exit 2; }
  done
  for step in "$@"; do run_step "$step"; done
}
