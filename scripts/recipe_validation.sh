#!/usr/bin/env bash
# Choosing seed 001's training recipe (issue 34) on validation suites, never on a test suite.
#
#   scripts/recipe_validation.sh run VARIANT...   # train and evaluate each variant (resumes)
#   scripts/recipe_validation.sh table            # the table over every variant measured
#   scripts/recipe_validation.sh list             # the variants and their overrides
#
# A variant is configs/residual_paper.toml (CONFIG) with some keys set (VARIANTS below; merged
# by scripts/config_variant.py). Each is trained on the town-a data of residual_paper.sh's
# train step (collected here when missing; a variant that sets collect.* keys gets its own data
# folder) and evaluated on two validation suites of town-a, regular and dense, drawn with their
# own seed (VAL_SEED, 20 tasks x 1 trial): the built-in 25-task test suites are never looked at.
# Finished evaluations are kept in KEEP (committed) and not run again.
# Environment knobs:
#   CD        the causaldrive binary       (default: build/causaldrive)
#   OUT       the experiment folder         (default: runs/recipe)
#   KEEP      the kept results              (default: results/residual_paper/recipe)
#   SEEDS     training seeds                (default: "0")
#   METHODS   methods trained per variant   (default: "bc-oh")
#   VAL_SEED  the validation suites' seed   (default: 9101)
#   VAL_TASKS tasks per validation suite    (default: 20)
#   WORKERS   evaluation workers            (default: 2)
set -euo pipefail

cd "$(dirname "$0")/.."
CD=${CD:-build/causaldrive}
CONFIG=${CONFIG:-configs/residual_paper.toml}
OUT=${OUT:-runs/recipe}
KEEP=${KEEP:-results/residual_paper/recipe}
SEEDS=${SEEDS:-"0"}
METHODS=${METHODS:-"bc-oh"}
VAL_SEED=${VAL_SEED:-9101}
VAL_TASKS=${VAL_TASKS:-20}
WORKERS=${WORKERS:-2}
TRIALS=1
DATA=${DATA:-runs/residual_paper/data/town-a}
source scripts/paper_lib.sh

# label|overrides (space-separated TABLE.KEY=VALUE). Each variant sets the three keys the
# recipe was chosen among, so that it means the same whatever CONFIG's defaults: "old" is the
# recipe of the tables before issue 34, "signed-hold-balanced" the one chosen.
OLD="model.pedals=two collect.hold_s=0.0 train.situation_weights=none"
VARIANTS=(
  "old|$OLD"
  "epochs24|$OLD train.epochs=24"
  "l2|$OLD train.loss=l2"
  "speed-input|$OLD model.speed_input=true"
  "balanced|model.pedals=two collect.hold_s=0.0 train.situation_weights=balanced"
  "hold|model.pedals=two collect.hold_s=1.0 train.situation_weights=none"
  "hold-balanced|model.pedals=two collect.hold_s=1.0 train.situation_weights=balanced"
  "signed|model.pedals=signed collect.hold_s=0.0 train.situation_weights=none"
  "signed-balanced|model.pedals=signed collect.hold_s=0.0 train.situation_weights=balanced"
  "signed-hold|model.pedals=signed collect.hold_s=1.0 train.situation_weights=none"
  "signed-hold-balanced|model.pedals=signed collect.hold_s=1.0 train.situation_weights=balanced"
)

overrides_of() {  # LABEL -> its overrides
  local entry name rest
  for entry in "${VARIANTS[@]}"; do
    name=${entry%%|*} rest=${entry#*|}
    if [[ $name == "$1" ]]; then echo "$rest"; return; fi
  done
  echo "error: unknown variant '$1' (scripts/recipe_validation.sh list)" >&2
  exit 2
}

config_of() {  # LABEL -> the variant's config file
  local file=$OUT/configs/$1.toml overrides
  overrides=$(overrides_of "$1")
  mkdir -p "$OUT/configs"
  # shellcheck disable=SC2086
  scripts/config_variant.py "$CONFIG" "$file" $overrides
  echo "$file"
}

data_of() {  # LABEL CONFIG -> the variant's data folder, collected when missing; variants
  local label=$1 config=$2 data=$DATA o key=""  # with the same collect.* keys share one
  for o in $(overrides_of "$label"); do [[ $o == collect.* ]] && key+="${o}_"; done
  [[ -n $key ]] && data=$OUT/data/$(printf '%s' "${key%_}" | tr -c 'a-zA-Z0-9._=-' '_')
  [[ -f $data/collect.json ]] || "$CD" collect --config "$config" --out "$data" >&2
  echo "$data"
}

val_suite() {  # KIND -> the validation suite file of town-a KIND
  local file=$OUT/suites/val-town-a-$1.json
  if [[ ! -f $file ]]; then
    mkdir -p "$OUT/suites"
    "$CD" suite --name "val-town-a-$1" --town town-a --traffic "$1" --tasks "$VAL_TASKS" \
      --trials 1 --seed "$VAL_SEED" --out "$file" >&2
  fi
  echo "$file"
}

run_variant() {
  local label=$1 config data=""
  config=$(config_of "$label")
  for s in $SEEDS; do
    for m in $METHODS; do
      local run=$OUT/train/$label/seed$s/$m kept=0
      for kind in regular dense; do
        [[ -f $(kept_of "$OUT/eval/$label/seed$s/$m/$kind")/results.json ]] && kept=$((kept + 1))
      done
      [[ $kept == 2 ]] && continue  # both evaluations kept: nothing to train (nor to collect)
      [[ -n $data || -f $run/best.pt ]] || data=$(data_of "$label" "$config")
      [[ -f $run/best.pt ]] || "$CD" train --config "$config" --method "$m" --data "$data" \
        --seed "$s" --out "$run"
      for kind in regular dense; do
        local suite; suite=$(val_suite "$kind")
        kept_eval "$OUT/eval/$label/seed$s/$m/$kind" --config "$config" --agent "$m" \
          --checkpoint "$run" --label "$label:$m" --suite "$suite" --trials 1 \
          --workers "$WORKERS" --quiet
      done
    done
  done
}

table() {
  local dirs=()
  mapfile -t dirs < <(find "$KEEP/eval" -name results.json -printf '%h\n' 2>/dev/null | sort)
  [[ ${#dirs[@]} -gt 0 ]] || { echo "error: nothing measured yet in $KEEP/eval" >&2; exit 1; }
  kept_report table failure "${dirs[@]}"
}

case ${1:-} in
  run)
    shift
    [[ $# -gt 0 ]] || { echo "error: name the variants to run (scripts/recipe_validation.sh list)" >&2; exit 2; }
    for v in "$@"; do overrides_of "$v" >/dev/null; done
    for v in "$@"; do run_variant "$v"; done
    ;;
  table) table ;;
  list) for entry in "${VARIANTS[@]}"; do echo "${entry%%|*}: ${entry#*|}"; done ;;
  *)
    awk 'NR > 1 && /^#/ { sub(/^# ?/, ""); print; next } NR > 1 { exit }' "$0"
    exit 2
    ;;
esac
