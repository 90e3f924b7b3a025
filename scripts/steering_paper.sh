#!/usr/bin/env bash
# Steering (ego.lateral = "free", issue 13): the expert and the headline tables of both seeds
# with the agent at the wheel, beside the route-mode runs of scripts/cim_paper.sh and
# scripts/residual_paper.sh.
#
#   scripts/steering_paper.sh expert    # the expert, route vs free, town-a/b/c regular and dense
#                                       # (built-in suites), and free on town-c suites drawn in
#                                       # free mode (routes that need lane changes)
#   scripts/steering_paper.sh bench     # bench world in both modes, one run each
#   scripts/steering_paper.sh train     # free-steering town-a data (steer, augmented frames) and
#                                       # the models of both tables, all seeds
#   scripts/steering_paper.sh table1    # seed 000's table 1 (cs, dim, rip, cim steering along its
#                                       # seed's dim path) on town-a/b regular, dense, stopgo
#   scripts/steering_paper.sh dense     # seed 001's comparison (bc-so, bc-oh, residual, dagger, hd,
#                                       # fca, keyframe) on town-a/b regular and dense
#   scripts/steering_paper.sh all       # the five above in order
#
# Several steps run in order (`scripts/steering_paper.sh train table1 dense`);
# an unknown step is refused before any of them runs.
# Every step resumes (collect, train and eval skip what their folders hold) and finished
# runs, evaluations and tables are kept in results/steering (scripts/paper_lib.sh), so a fresh
# checkout evaluates the weights an earlier session trained. The experiment
# configs are the papers' configs with [ego] lateral = "free" and a share of augmented frames
# added ($OUT/configs). Knobs:
#   CD       the causaldrive binary        (default: build/causaldrive)
#   OUT      the experiment folder          (default: runs/steering)
#   KEEP     the kept results               (default: results/steering)
#   SEEDS    training seeds                 (default: "0 1 2")
#   TASKS    tasks per suite; 25 uses the built-in suites (default: 25)
#   TRIALS   trials per task                (default: 1)
#   WORKERS  evaluation workers             (default: 2)
#   AUGMENT  collect.augment.fraction of the free data (default: 0.3)
#   METHODS  seed 001's methods of train and dense (default: all seven)
#   BENCH_STEPS, BENCH_SLICES  bench world's steps per loop and slices (default: 120000, 60;
#            the per-slice ratio varies with the task, so the median wants many slices)
set -euo pipefail

cd "$(dirname "$0")/.."
CD=${CD:-build/causaldrive}
OUT=${OUT:-runs/steering}
SEEDS=${SEEDS:-"0 1 2"}
TASKS=${TASKS:-25}
TRIALS=${TRIALS:-1}
WORKERS=${WORKERS:-2}
AUGMENT=${AUGMENT:-0.3}
METHODS=${METHODS:-"bc-so bc-oh residual dagger hd fca keyframe"}
BENCH_STEPS=${BENCH_STEPS:-120000}
BENCH_SLICES=${BENCH_SLICES:-60}
CONFIG=configs/quickstart.toml  # the expert and bench steps; the tables set their own
source scripts/paper_lib.sh

# free_config NAME BASE: BASE with a free-steering ego and augmented frames, as $OUT/configs/NAME.
# BASE pins its route-mode tables with a `lateral = "route"` line, which becomes "free".
free_config() {
  local file=$OUT/configs/$1.toml
  if ! grep -q '^lateral = "route"' "$2"; then
    echo "steering_paper.sh: $2 has no 'lateral = \"route\"' line to make \"free\"" >&2
    return 1
  fi
  mkdir -p "$OUT/configs"
  { sed 's/^lateral = "route".*/lateral = "free"/' "$2"
    printf '\n[collect.augment]\nfraction = %s\n' "$AUGMENT"; } > "$file.tmp" && mv "$file.tmp" "$file"
  echo "$file"
}

# drawn_suite MODE TRAFFIC: a town-c suite drawn by a MODE ego (seed 4242), kept in $KEEP/suites.
drawn_suite() {
  local file=$KEEP/suites/town-c-$2-$1.json
  if [[ ! -f $file ]]; then
    mkdir -p "$KEEP/suites"
    "$CD" suite --config "$(mode_config "$1")" --name "town-c-$2-$1" --town town-c \
      --traffic "$2" --tasks "$TASKS" --trials "$TRIALS" --seed 4242 --out "$file" >&2
  fi
  echo "$file"
}

expert_step() {
  local dirs=() mode name suite
  for mode in route free; do
    for name in town-a-regular town-a-dense town-b-regular town-b-dense town-c-regular \
                town-c-dense; do
      suite=$(suite_of "$name")
      # town-c has no built-in dense suite: one drawn by a route-mode ego, as the built-in ones.
      [[ $name == town-c-dense ]] && suite=$(drawn_suite route dense)
      kept_eval "$OUT/eval/expert-$mode/$name" --config "$(mode_config "$mode")" --agent expert \
        --label "expert-$mode" --suite "$suite" --trials "$TRIALS" --workers "$WORKERS" --quiet
      dirs+=("$KEPT")
    done
  done
  # Routes that need lane changes: drawn by a free ego (it starts on the rightmost lane).
  for traffic in regular dense; do
    local file
    file=$(drawn_suite free "$traffic")
    kept_eval "$OUT/eval/expert-free/town-c-$traffic-free" --config "$(mode_config free)" \
      --agent expert --label expert-free --suite "$file" --workers "$WORKERS" --quiet
    dirs+=("$KEPT")
  done
  kept_report expert outcomes,lateral "${dirs[@]}"
  cat "$OUT/expert.md"
}

bench_step() {
  local mode
  for mode in route free; do
    local f=$OUT/bench/world-$mode.json
    [[ -f $KEEP/bench/world-$mode.json ]] && continue
    mkdir -p "$(dirname "$f")"
    "$CD" bench world --config "$(mode_config "$mode")" --steps "$BENCH_STEPS" \
      --slices "$BENCH_SLICES" --json \
      > "$f.tmp" && mv "$f.tmp" "$f"
    keep_file "$f"
  done
  cat "$KEEP"/bench/world-*.json
}

train_step() {
  local cim_cfg res_cfg s m
  cim_cfg=$(free_config cim configs/cim_paper.toml)
  res_cfg=$(free_config residual configs/residual_paper.toml)
  # Both papers' configs collect the same town-a data (120 noisy expert episodes, seed 100).
  "$CD" collect --config "$res_cfg" --out "$OUT/data/town-a"
  for s in $SEEDS; do
    for m in cim dim rip; do
      OUT=$OUT/cim KEEP=$KEEP/cim kept_train "$OUT/cim/train/seed$s/$m" --config "$cim_cfg" \
        --method "$m" --data "$OUT/data/town-a" --seed "$s"
    done
    for m in $METHODS; do
      OUT=$OUT/residual KEEP=$KEEP/residual kept_train "$OUT/residual/train/seed$s/$m" \
        --config "$res_cfg" --method "$m" --data "$OUT/data/town-a" --seed "$s"
    done
  done
}

run_step() {
  case $1 in
    expert) expert_step ;;
    bench) bench_step ;;
    train) train_step ;;
    table1)
      CONFIG=$(free_config cim configs/cim_paper.toml) OUT=$OUT/cim KEEP=$KEEP/cim CIM_PATH=dim \
        eval_agents table1 all,lateral clean \
        "town-a-regular town-a-dense town-a-stopgo town-b-regular town-b-dense town-b-stopgo" \
        cs dim rip cim
      ;;
    dense)
      CONFIG=$(free_config residual configs/residual_paper.toml) OUT=$OUT/residual \
        KEEP=$KEEP/residual eval_agents dense failure,lateral clean \
        "town-a-regular town-a-dense town-b-regular town-b-dense" $METHODS
      ;;
    all)
      for step in expert bench train table1 dense; do run_step "$step"; done
      ;;
  esac
}

run_steps "expert bench train table1 dense all" "$@"
