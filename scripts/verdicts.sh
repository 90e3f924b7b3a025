#!/usr/bin/env bash
# The verdicts of issue 47, run by the protocol written before them (docs/protocol.md).
#
#   scripts/verdicts.sh tune     # section 6: the four variants x every method at seed 0 on the
#                                # validation suites (scripts/recipe_validation.sh; resumes, and
#                                # a method's kept evaluations are not trained again)
#   scripts/verdicts.sh choose   # section 6's rule over the kept validation runs: the chosen
#                                # variant per METHODS -> configs/verdicts/METHOD.toml, and
#                                # results/verdicts/tuning.md (every method tuned so far)
#   scripts/verdicts.sh data     # section 4: D1 and D2 (collect seeds 100, 200) for each
#                                # method's chosen collect settings
#   scripts/verdicts.sh train    # section 7: seeds 0-9 (residual, bc-oh, keyframe, dagger) and
#                                # 0-4 (bc-so, hd, fca), seed s on D1 (even) or D2 (odd)
#   scripts/verdicts.sh eval     # sections 2 and 5: every run on the six conditions
#   scripts/verdicts.sh ablations  # section 2's ablations, seeds 0-4 (SEEDS_OTHERS): two-stream
#                                # bc-oh and keyframe (table 11), residual with 2 and 4 memory
#                                # branches (B.5), each from its base method's chosen config
#   scripts/verdicts.sh secondary  # the ablations on verdicts-town-a-dense, and every section-7
#                                # run on the stop-and-go suites (town-a-stopgo, town-b-stopgo);
#                                # a run without weights here (not trained yet, or over 5 MB and
#                                # trained elsewhere) is named and skipped, for a later call
#   scripts/verdicts.sh probe    # the copycat probe (causaldrive probe) of every trained
#                                # history run, on the data folder it did not train on (the
#                                # camera's: its episodes replayed, docs/methods.md)
#   scripts/verdicts.sh gpu-list # for a lent GPU (docs/gpu.md): GPU_DIR/runs.txt lists every
#                                # run of train, ablations and the device check (cuda/) not
#                                # trained yet (residual's train runs are the CPU's and
#                                # dagger's rollouts need SUMO: neither is listed), with its
#                                # config (cuda_deterministic)
#                                # and data folder (.tar.xz) beside it, for scripts/gpu_runs.py;
#                                # scripts/gpu_import.py brings the packs back
#   scripts/verdicts.sh report   # the primary endpoint and residual against each method
#                                # -> results/verdicts/primary.md; tables 11 and B.5, the stall
#                                # rates -> results/verdicts/secondary.md
#
# MODE=free runs section 2's free-mode endpoint (ego.lateral = "free": the agents steer):
# residual, bc-oh, keyframe and dagger at seeds 0-4, each with its chosen config of route mode's
# tuning (configs/verdicts/METHOD.toml, section 6: no tuning of its own) and the free keys
# (ego.lateral = "free", collect.augment.fraction = AUGMENT, default 0.3, as
# scripts/steering_paper.sh), written to runs/verdicts-free/configs/; its own data folders
# (collect seeds 100 and 200), runs and six conditions under runs/verdicts-free and
# results/verdicts-free (`MODE=free scripts/verdicts.sh data train eval report`). tune and
# choose are route mode's; no ablation runs in free mode. With VIEW=camera: runs/camera-free.
#
# VIEW=camera runs the same steps as docs/camera.md's plan for the front camera: the base config
# is configs/residual_paper.toml with sense.view = "camera"; the methods bc-so, bc-oh, keyframe
# and residual (dagger where compute allows: METHODS) at seeds 0-2; the conditions are table 7's
# (town-a regular and dense, the training weathers), table 8's (the same suites with
# sense.camera.weather = "held-out") and table 9's (town-b); the ablations are table 11's
# two-stream runs; its folders are runs/camera, results/camera (tuning under its recipe/) and
# configs/camera. gpu-list is the BEV's only (a camera data folder, ~300 MB, does not travel).
#
# Several steps run in order (`scripts/verdicts.sh tune choose`); an unknown step is refused
# before any of them runs. Knobs:
#   CD       the causaldrive binary   (default: build/causaldrive)
#   VIEW     bev (default: docs/protocol.md's runs) or camera (docs/camera.md's plan)
#   MODE     route (default: the primary endpoint's) or free (the free-mode endpoint, above)
#   METHODS  the methods tuned, trained, evaluated (default: the seven of section 3; camera:
#            bc-so bc-oh keyframe residual)
#   SEEDS_MAIN, SEEDS_OTHERS  section 7's seeds (default: "0 1 ... 9" for residual, bc-oh,
#            keyframe, dagger; "0 1 2 3 4" for the others; camera: "0 1 2" for all)
#   SEEDS_ADDED  the seeds section 7's power rule adds to residual (CPU and the device check's
#            CUDA) and bc-oh only (default: none; "10 11 12 13 14" once docs/verdicts.md's
#            power row says they are added)
#   WORKERS  evaluation workers       (default: 2)
#   TRAIN    the runs `eval` evaluates: train (section 7's, default) or cuda (the device
#            check's runs of protocol section 11, labelled METHOD-cuda; untrained seeds skipped);
#            cpu: `train` trains METHODS again on this CPU at their section-7 seeds, configs and
#            data folders into cpu/seedN/METHOD, and `eval` evaluates those in the six
#            conditions, labelled METHOD-cpu (protocol section 11, session 40: keyframe, whose
#            section-7 runs trained on CUDA); `secondary` refuses it, as `ablations`, `probe`
#            and `gpu-list` do;
#            retrain: `train` retrains METHODS at SEEDS_RETRAIN into retrain/seedN/METHOD and
#            `secondary` evaluates those on the stop-and-go suites only, labelled
#            METHOD-retrain (protocol section 11, session 39: residual's stall rate, whose
#            section-7 weights are not kept); `eval`, `ablations`, `probe` and `gpu-list`
#            refuse it, and `train` refuses cuda (those runs train on a lent GPU)
#   SEEDS_RETRAIN  the seeds of TRAIN=retrain (default: "0 1 2 3 4")
#   ABLATION_LABELS  the ablations trained and evaluated (default: all four; camera: the two
#            two-stream ones)
#   GPU_DIR  gpu-list's folder (default: .gpu/verdicts, which git ignores)
#   VAL, CONFIGS, RESULTS  choose's input and output folders (default: the kept validation
#            runs, configs/verdicts, results/verdicts; camera: results/camera/recipe/eval,
#            configs/camera, results/camera)
set -euo pipefail

cd "$(dirname "$0")/.."
CD=${CD:-build/causaldrive}
VIEW=${VIEW:-bev}
BASE=configs/residual_paper.toml  # every config here is BASE with BASE_KEYS and a variant's keys
# The six conditions of section 2: suite|sensor|folder name. A sensor is the BEV's clean or
# shifted (eval --sensor), or the camera's held-out weathers (sense.camera.weather).
case $VIEW in
  bev)
    BASE_KEYS=""
    view_methods="residual bc-oh keyframe dagger bc-so hd fca"
    view_main="0 1 2 3 4 5 6 7 8 9" view_others="0 1 2 3 4"
    view_name=verdicts view_title="the verdicts"
    view_val=results/residual_paper/recipe view_tune_out=runs/recipe  # recipe_validation.sh's
    view_ablations="two-stream-bc-oh two-stream-keyframe residual-b2 residual-b4"
    CONDITIONS="verdicts-town-a-regular|clean|a-regular verdicts-town-a-dense|clean|a-dense
verdicts-town-a-regular|shifted|a-regular-shifted verdicts-town-a-dense|shifted|a-dense-shifted
verdicts-town-b-regular|clean|b-regular verdicts-town-b-dense|clean|b-dense"
    ;;
  camera)
    BASE_KEYS="sense.view=camera"
    view_methods="residual bc-oh keyframe bc-so"
    view_main="0 1 2" view_others="0 1 2"
    view_name=camera view_title="the camera runs"
    view_val=results/camera/recipe view_tune_out=""  # set below: $OUT/recipe
    view_ablations="two-stream-bc-oh two-stream-keyframe"
    CONDITIONS="verdicts-town-a-regular|clean|a-regular verdicts-town-a-dense|clean|a-dense
verdicts-town-a-regular|held-out|a-regular-held-out verdicts-town-a-dense|held-out|a-dense-held-out
verdicts-town-b-regular|clean|b-regular verdicts-town-b-dense|clean|b-dense"
    ;;
  *) echo "error: unknown VIEW '$VIEW' (bev or camera)" >&2; exit 2 ;;
esac
MODE=${MODE:-route}
case $MODE in
  route) FREE_KEYS="" ;;
  free)  # section 2's free-mode endpoint: the chosen configs of route mode with the free keys
    FREE_KEYS="ego.lateral=free collect.augment.fraction=${AUGMENT:-0.3}"
    view_configs=configs/$view_name
    view_name=$view_name-free view_title="the free-mode ${view_title#the }"
    [[ $VIEW == bev ]] && view_methods="residual bc-oh keyframe dagger" view_main="0 1 2 3 4"
    view_ablations=""
    ;;
  *) echo "error: unknown MODE '$MODE' (route or free)" >&2; exit 2 ;;
esac
METHODS=${METHODS:-$view_methods}
VARIANTS="old signed hold-balanced signed-hold-balanced"
OUT=${OUT:-runs/$view_name}
view_tune_out=${view_tune_out:-$OUT/recipe}
SEEDS_MAIN=${SEEDS_MAIN:-$view_main}
SEEDS_OTHERS=${SEEDS_OTHERS:-$view_others}
SEEDS_ADDED=${SEEDS_ADDED:-""}
WORKERS=${WORKERS:-2}
TRAIN=${TRAIN:-train}  # the runs trained and evaluated: section 7's (train) or section 11's
case $TRAIN in
  train | cpu | cuda | retrain) ;;
  *) echo "error: unknown TRAIN '$TRAIN' (train, cpu, cuda or retrain)" >&2; exit 2 ;;
esac
SEEDS_RETRAIN=${SEEDS_RETRAIN:-"0 1 2 3 4"}
KEEP=${KEEP:-results/$view_name}
source scripts/paper_lib.sh  # run_steps, kept_train, kept_eval
VAL=${VAL:-$view_val/eval}                  # recipe_validation.sh's kept evaluations
CONFIGS=${CONFIGS:-${view_configs:-configs/$view_name}}  # choose's configs (free: route's)
RESULTS=${RESULTS:-results/$view_name}      # choose's tuning.md

base_config() {  # -> BASE with BASE_KEYS: BASE itself, or $OUT/configs/base.toml
  [[ -n $BASE_KEYS ]] || { echo "$BASE"; return; }
  mkdir -p "$OUT/configs"
  # shellcheck disable=SC2086
  scripts/config_variant.py "$BASE" "$OUT/configs/base.toml" $BASE_KEYS >&2 || return
  echo "$OUT/configs/base.toml"
}

tune() {
  local m config
  config=$(base_config)
  for m in $METHODS; do
    SEEDS=0 METHODS=$m CD=$CD CONFIG=$config OUT=$view_tune_out KEEP=${VAL%/eval} \
      scripts/recipe_validation.sh run $VARIANTS
  done
}

choose() {
  mkdir -p "$CONFIGS" "$RESULTS"
  local choices
  choices=$(python3 - "$VAL" "$METHODS" "$VARIANTS" "$RESULTS" "$view_methods" <<'EOF'
import glob, json, os, sys

val, methods, variants, results = sys.argv[1], sys.argv[2].split(), sys.argv[3].split(), sys.argv[4]
# The table holds every method tuned so far (the view's methods, METHODS, then any other with a
# kept validation run), so choosing for one method keeps the others' rows; configs are written
# for METHODS only.
tabled = []
for m in sys.argv[5].split() + methods + sorted(
        os.path.basename(d) for d in glob.glob(os.path.join(val, "*", "seed0", "*"))):
    if m not in tabled:
        tabled.append(m)
lines = ["# Equal tuning (docs/protocol.md section 6): seed 0, validation suites of town-a",
         "", "Generated by `scripts/verdicts.sh choose` from the kept validation runs "
         "(`%s`). Rule: the highest mean success over the two "
         "suites; ties: the lower mean collision rate, then the order old, signed, hold-balanced, "
         "signed-hold-balanced." % val, "",
         "| method | variant | regular success / collision % | dense success / collision % | mean success % | chosen |",
         "|---|---|---|---|---:|---|"]
missing = []
for m in tabled:
    scores = []
    for order, v in enumerate(variants):
        s = {}
        for kind in ("regular", "dense"):
            f = os.path.join(val, v, "seed0", m, kind, "results.json")
            if not os.path.exists(f):
                missing.append(f)
                break
            s[kind] = json.load(open(f))["summary"]
        if len(s) < 2:
            continue
        succ = (s["regular"]["success_rate"] + s["dense"]["success_rate"]) / 2
        coll = (s["regular"]["collision_rate"] + s["dense"]["collision_rate"]) / 2
        scores.append((-succ, coll, order, v, s, succ))
    if len(scores) < len(variants):
        continue
    best = min(scores)[3]
    for _, _, _, v, s, succ in scores:
        lines.append("| %s | %s | %.1f / %.1f | %.1f / %.1f | %.1f | %s |" % (
            m, v, 100 * s["regular"]["success_rate"], 100 * s["regular"]["collision_rate"],
            100 * s["dense"]["success_rate"], 100 * s["dense"]["collision_rate"], 100 * succ,
            "**yes**" if v == best else ""))
    chosen = [x for x in scores if x[3] == best][0]
    if m in methods:
        print("CHOICE %s %s %.1f" % (m, best, 100 * chosen[5]))
with open(results + "/tuning.md.tmp", "w") as out:
    out.write("\n".join(lines) + "\n")
    if missing:
        out.write("\nNot measured yet (the rule waits for all four variants of a method):\n\n")
        out.write("".join("- `%s`\n" % f for f in missing))
os.replace(results + "/tuning.md.tmp", results + "/tuning.md")
EOF
)
  local tag m v pct overrides
  while read -r tag m v pct; do
    [[ $tag == CHOICE ]] || continue
    overrides=$(scripts/recipe_validation.sh list | sed -n "s/^$v: //p")
    # shellcheck disable=SC2086
    scripts/config_variant.py "$BASE" "$CONFIGS/$m.toml.body" $BASE_KEYS $overrides
    { printf '# %s for %s: variant "%s", chosen by docs/protocol.md section 6 (the\n' "$m" "$view_title" "$v"
      printf '# highest mean success over val-town-a-regular and val-town-a-dense at seed 0, ties by\n'
      printf '# lower collision then list order; %s %% here; %s/tuning.md). Written by\n' "$pct" "$RESULTS"
      printf '# scripts/verdicts.sh choose: %s with%s the variant keys.\n\n' "$BASE" \
        "${BASE_KEYS:+ $BASE_KEYS and}"
      cat "$CONFIGS/$m.toml.body"; } > "$CONFIGS/$m.toml.tmp"
    rm "$CONFIGS/$m.toml.body"
    mv "$CONFIGS/$m.toml.tmp" "$CONFIGS/$m.toml"
  done <<<"$choices"
  cat "$RESULTS/tuning.md"
}

seeds_of() {  # METHOD -> its training seeds (section 7; TRAIN=retrain: SEEDS_RETRAIN)
  [[ $TRAIN != retrain ]] || { echo "$SEEDS_RETRAIN"; return; }
  case $1 in
    residual | bc-oh) echo "$SEEDS_MAIN $SEEDS_ADDED" ;;
    keyframe | dagger) echo "$SEEDS_MAIN" ;;
    *) echo "$SEEDS_OTHERS" ;;
  esac
}

config_of() {  # METHOD -> its chosen config (section 6; MODE=free: with the free keys, in
  local f=$CONFIGS/$1.toml  # $OUT/configs), or a one-line stop
  [[ -f $f ]] || { echo "error: $f missing: run 'scripts/verdicts.sh tune choose' first" >&2; return 1; }
  [[ -n $FREE_KEYS ]] || { echo "$f"; return; }
  mkdir -p "$OUT/configs"
  # shellcheck disable=SC2086
  scripts/config_variant.py "$f" "$OUT/configs/$1.toml" $FREE_KEYS >&2 || return
  echo "$OUT/configs/$1.toml"
}

data_of() {  # METHOD SEED -> its data folder: D1 (even seed) or D2, for its collect settings
  local config hold d
  config=$(config_of "$1") || return
  hold=$(python3 -c 'import sys, tomllib; print(tomllib.load(open(sys.argv[1], "rb")).get("collect", {}).get("hold_s", 1.0))' "$config")
  d=D$(( $2 % 2 + 1 ))
  echo "$OUT/data/hold$hold/$d"
}

data_step() {
  local m s config dir seed
  for m in $METHODS; do
    config=$(config_of "$m") || return
    for s in 0 1; do
      dir=$(data_of "$m" "$s") || return
      seed=$(( s == 0 ? 100 : 200 ))
      [[ -f $dir/collect.json ]] || "$CD" collect --config "$config" --seed "$seed" --out "$dir"
    done
  done
}

train_step() {
  local m s config
  if [[ $TRAIN == cuda ]]; then
    echo "error: TRAIN=cuda runs train on a lent GPU (scripts/verdicts.sh gpu-list, docs/gpu.md), not here" >&2
    return 1
  fi
  for m in $METHODS; do
    config=$(config_of "$m") || return
    for s in $(seeds_of "$m"); do
      kept_train "$OUT/$TRAIN/seed$s/$m" --config "$config" --method "$m" \
        --data "$(data_of "$m" "$s")" --seed "$s" || return
    done
  done
}

# Section 2's ablations: label|the method whose chosen config (section 6) and data folder they
# take|the keys set on it. Each trains `--method residual` (the two-stream network) at the seeds
# of SEEDS_OTHERS and is compared with its base method on verdicts-town-a-dense.
ABLATIONS="two-stream-bc-oh|bc-oh|residual.policy_input=history residual.memory_target=action
two-stream-keyframe|keyframe|residual.policy_input=history residual.memory_target=action residual.weights=keyframe
residual-b2|residual|residual.branches=2
residual-b4|residual|residual.branches=4"
ABLATION_LABELS=${ABLATION_LABELS:-$view_ablations}

ablation_base() {  # LABEL -> its base method, or a one-line stop
  local base
  base=$(awk -F'|' -v l="$1" '$1 == l { print $2 }' <<<"$ABLATIONS")
  [[ -n $base ]] || { echo "error: unknown ablation '$1' (known: $(cut -d'|' -f1 <<<"$ABLATIONS" | tr '\n' ' '))" >&2; return 1; }
  echo "$base"
}

ablation_config() {  # LABEL -> $OUT/configs/LABEL.toml: the base method's config with its keys
  local base keys file=$OUT/configs/$1.toml
  base=$(ablation_base "$1") || return
  keys=$(awk -F'|' -v l="$1" '$1 == l { print $3 }' <<<"$ABLATIONS")
  mkdir -p "$OUT/configs"
  # shellcheck disable=SC2086
  scripts/config_variant.py "$(config_of "$base")" "$file" $keys >&2 || return
  echo "$file"
}

ablations_step() {
  local label base config s
  only_section7 ablations || return
  for label in $ABLATION_LABELS; do
    base=$(ablation_base "$label") || return
    config=$(ablation_config "$label") || return
    for s in $SEEDS_OTHERS; do
      kept_train "$OUT/train/seed$s/$label" --config "$config" --method residual \
        --data "$(data_of "$base" "$s")" --seed "$s" || return
    done
  done
}

run_label() {  # METHOD -> the label of its TRAIN runs: METHOD, or METHOD-TRAIN (-cpu, -cuda,
               # -retrain)
  if [[ $TRAIN == train ]]; then echo "$1"; else echo "$1-$TRAIN"; fi
}

only_section7() {  # STEP: a one-line stop unless TRAIN is train (or cpu or cuda, STEP eval)
  [[ $TRAIN == train || ( ( $TRAIN == cpu || $TRAIN == cuda ) && $1 == eval ) ]] && return 0
  echo "error: TRAIN=$TRAIN: $1 is not run for these runs (protocol section 11)" >&2
  return 1
}

has_weights() {  # RUN: a finished run whose weights are here: kept in git, or kept as a
  local kept; kept=$(kept_of "$1")  # record with its weights (over 5 MB) in RUN. A best.pt
  [[ -d $kept || ( -d $kept.record && -f $1/best.pt ) ]]  # alone is an unfinished run's.
}

# secondary_eval RUN FOLDER ARGS...: kept_eval FOLDER of RUN, unless kept already; a RUN
# without weights here is named and counted in the caller's `skipped`.
secondary_eval() {
  local run=$1 folder=$2; shift 2
  [[ -f $(kept_of "$folder")/results.json ]] && return 0
  if ! has_weights "$run"; then
    echo "$run: no weights here (not trained yet, or not kept), $folder skipped" >&2
    skipped=$((skipped + 1))
    return 0
  fi
  restore_run "$run" || return
  kept_eval "$folder" --checkpoint "$run" "$@" --trials 1 --workers "$WORKERS" --quiet
}

# Evaluates what has weights and names what it skips: a run not trained yet, or one whose
# weights (over 5 MB: residual's) were not kept and are not on this machine, is left for a
# later call. A kept evaluation is never run again, weights or none.
secondary_step() {
  local label config s m suite skipped=0 ablations=$ABLATION_LABELS
  [[ $TRAIN != cpu ]] || { only_section7 secondary; return; }  # the six conditions only
  [[ $TRAIN == train ]] || ablations=""  # retrain (cuda): their stop-and-go runs alone
  for label in $ablations; do
    config=$(ablation_config "$label") || return
    for s in $SEEDS_OTHERS; do
      secondary_eval "$OUT/train/seed$s/$label" "$OUT/eval/$label/seed$s/a-dense" \
        --config "$config" --agent residual --label "$label" --suite verdicts-town-a-dense || return
    done
  done
  for m in $METHODS; do
    config=$(config_of "$m") || return
    for s in $(seeds_of "$m"); do
      for suite in town-a-stopgo town-b-stopgo; do
        secondary_eval "$OUT/$TRAIN/seed$s/$m" "$OUT/eval/$(run_label "$m")/seed$s/${suite#town-}" \
          --config "$config" --agent "$m" --label "$(run_label "$m")" --suite "$suite" || return
      done
    done
  done
  (( skipped == 0 )) || echo "secondary: $skipped evaluation(s) skipped for want of weights (above)" >&2
}

probe_step() {  # the probe's row (protocol section 11): each trained run of a history method
  local m s run
  only_section7 probe || return
  for m in $METHODS; do
    [[ $m == bc-so ]] && continue  # no history to probe
    for s in $(seeds_of "$m"); do
      run=$OUT/train/seed$s/$m
      has_weights "$run" || continue  # not trained yet
      restore_run "$run" || return
      kept_json "$OUT/probe/seed$s/$m.json" "$CD" probe --checkpoint "$run" \
        --data "$(data_of "$m" $((s + 1)))" --max-frames 2000 --json || return
    done
  done
}

GPU_DIR=${GPU_DIR:-.gpu/verdicts}

gpu_entry() {  # NAME METHOD CONFIG BASE SEED: one line of GPU_DIR/runs.txt.tmp, unless trained
  local name=$1 method=$2 config=$3 base=$4 seed=$5 kept data tag cfg
  kept=$(kept_of "$OUT/$name")
  [[ -d $kept || -d $kept.record ]] && return 0
  data=$(data_of "$base" "$seed") || return
  if [[ ! -f $data/collect.json ]]; then
    echo "$name: not listed, $data is not collected yet (scripts/verdicts.sh data)" >&2
    return 0
  fi
  tag=$(tr '/' '-' <<<"${data#"$OUT"/data/}")
  if [[ ! -f $GPU_DIR/$tag.tar.xz ]]; then
    tar -C "$data" --exclude causaldrive.lock -cJf "$GPU_DIR/$tag.tar.xz.tmp" . || return
    mv "$GPU_DIR/$tag.tar.xz.tmp" "$GPU_DIR/$tag.tar.xz"
  fi
  cfg=$GPU_DIR/$(basename "$config")
  scripts/config_variant.py "$config" "$cfg" train.cuda_deterministic=true >&2 || return
  echo "$name $method $cfg $GPU_DIR/$tag.tar.xz $seed" >>"$GPU_DIR/runs.txt.tmp"
}

gpu_list_step() {
  local s m label methods=""
  [[ $TRAIN != retrain && $TRAIN != cpu ]] || { echo "error: TRAIN=$TRAIN: its runs train on this machine's CPU (protocol section 11, sessions 39-40), not on a lent GPU" >&2; return 1; }
  if [[ $VIEW != bev ]]; then
    echo "error: gpu-list lists the BEV's runs only: a camera data folder (~300 MB) does not fit a lent machine's 64 MiB carry" >&2
    return 1
  fi
  mkdir -p "$GPU_DIR"
  for m in $METHODS; do
    if [[ $m == dagger ]]; then
      echo "dagger: not listed, its rollouts need SUMO (trained here)" >&2
    elif [[ ! -f $CONFIGS/$m.toml ]]; then
      echo "$m: not listed, no chosen config yet (scripts/verdicts.sh tune choose)" >&2
    else
      methods+=" $m"
    fi
  done
  echo "# scripts/verdicts.sh gpu-list: the runs not trained yet, seeds outer (NAME METHOD CONFIG DATA SEED)" \
    >"$GPU_DIR/runs.txt.tmp"
  # Seeds outer, so a deadline on the lent machine leaves every method short by about as much.
  for s in $(tr ' ' '\n' <<<"$SEEDS_MAIN $SEEDS_ADDED $SEEDS_OTHERS" | grep . | sort -un); do
    for m in $methods; do
      [[ " $(seeds_of "$m") " == *" $s "* ]] || continue
      # residual's section-7 runs train on this machine's CPU (protocol section 11); its
      # CUDA runs are the device check's, below.
      [[ $m == residual ]] && continue
      gpu_entry "train/seed$s/$m" "$m" "$(config_of "$m")" "$m" "$s" || return
    done
    # The device check (protocol section 11): residual on CUDA at section 7's seeds (route mode).
    if [[ $MODE == route && " $methods " == *" residual "* && " $(seeds_of residual) " == *" $s "* ]]; then
      gpu_entry "cuda/seed$s/residual" residual "$(config_of residual)" residual "$s" || return
    fi
    [[ " $SEEDS_OTHERS " == *" $s "* ]] || continue
    for label in $ABLATION_LABELS; do
      gpu_entry "train/seed$s/$label" residual "$(ablation_config "$label")" \
        "$(ablation_base "$label")" "$s" || return
    done
  done
  mv "$GPU_DIR/runs.txt.tmp" "$GPU_DIR/runs.txt"
  echo "$GPU_DIR/runs.txt: $(grep -vc '^#' "$GPU_DIR/runs.txt") runs"
}

condition_names() {  # the six folder names, space-separated
  local c
  for c in $CONDITIONS; do printf '%s ' "${c##*|}"; done
}

eval_dirs=()
eval_step() {
  local m s config cfg held_out c suite sensor name run label
  only_section7 eval || return
  eval_dirs=()
  for m in $METHODS; do
    config=$(config_of "$m") || return
    held_out=$OUT/configs/$m-held-out.toml  # the camera's table 8: the held-out weathers
    if [[ $CONDITIONS == *"|held-out|"* ]]; then
      mkdir -p "$OUT/configs"
      scripts/config_variant.py "$config" "$held_out" sense.camera.weather=held-out >&2 || return
    fi
    # TRAIN=cuda (cpu): section 11's runs, labelled METHOD-cuda (METHOD-cpu).
    label=$(run_label "$m")
    for s in $(seeds_of "$m"); do
      run=$OUT/$TRAIN/seed$s/$m
      if [[ $TRAIN != train ]] && ! has_weights "$run"; then
        echo "$run: no weights here (not trained yet, or not on this machine), skipped" >&2
        continue
      fi
      for c in $CONDITIONS; do
        IFS='|' read -r suite sensor name <<<"$c"
        cfg=$config
        [[ $sensor != held-out ]] || cfg=$held_out sensor=clean
        restore_run "$run" || return
        kept_eval "$OUT/eval/$label/seed$s/$name" --config "$cfg" --agent "$m" \
          --checkpoint "$run" --label "$label" --suite "$suite" --trials 1 \
          --workers "$WORKERS" --sensor "$sensor" --quiet
        eval_dirs+=("$KEPT")
      done
    done
  done
}

BASELINES="bc-oh keyframe dagger bc-so hd fca"  # section 3's methods against residual

report_step() {
  local dirs=() m a f=$OUT/primary.md
  # The primary endpoint reads the six conditions' folders of section 3's methods alone
  # (section 2), never the secondary step's stop-and-go or ablation runs.
  mapfile -t dirs < <(find "$KEEP/eval" -name results.json -printf '%h\n' 2>/dev/null |
                      grep -E "/($(condition_names | xargs | tr ' ' '|'))\$" |
                      grep -vE "/eval/($(cut -d'|' -f1 <<<"$ABLATIONS" | xargs | tr ' ' '|'))/" | sort)
  [[ ${#dirs[@]} -gt 0 ]] || { echo "error: nothing evaluated yet in $KEEP/eval" >&2; return 1; }
  mkdir -p "$OUT"
  compare_section() {  # A B: report --compare's section of A - B over the six conditions
    echo
    "$CD" report "${dirs[@]}" --metrics outcomes --compare "$1" "$2" | sed -n '/^## .* vs /,$p' || true
  }
  {
    echo "# ${view_title^}' primary endpoint (docs/protocol.md section 2), from the kept evaluations"
    echo
    "$CD" report "${dirs[@]}" --metrics outcomes
    for m in $BASELINES; do
      [[ " ${dirs[*]} " == *"/eval/$m/"* ]] || continue  # not evaluated (yet)
      compare_section residual "$m"
    done
    # The device check (section 11): residual trained on CUDA against the CUDA-trained
    # methods, and against residual trained on the CPU.
    if [[ " ${dirs[*]} " == *"/eval/residual-cuda/"* ]]; then  # (not grep -q: pipefail and SIGPIPE)
      for m in bc-oh keyframe residual; do compare_section residual-cuda "$m"; done
    fi
    # Section 11 (session 40): a method trained again on the CPU against residual (CPU) and
    # against its own section-7 runs.
    for m in $BASELINES; do
      [[ " ${dirs[*]} " == *"/eval/$m-cpu/"* ]] || continue
      for a in residual "$m"; do compare_section "$a" "$m-cpu"; done
    done
    echo
    "$CD" report "${dirs[@]}" --metrics outcomes --power | sed -n '/^## Power/,$p'
  } > "$f.tmp"
  mv "$f.tmp" "$f"
  keep_file "$f"
  secondary_report
}

secondary_report() {  # tables 11 and B.5 on town-a dense, the stall rates -> secondary.md
  local f=$OUT/secondary.md dense=() stopgo=() label base
  mapfile -t dense < <(find "$KEEP/eval" -path '*/a-dense/results.json' -printf '%h\n' 2>/dev/null | sort)
  mapfile -t stopgo < <(find "$KEEP/eval" -path '*-stopgo/results.json' -printf '%h\n' 2>/dev/null | sort)
  [[ ${#dense[@]} -gt 0 || ${#stopgo[@]} -gt 0 ]] || return 0
  {
    echo "# ${view_title^}' secondary endpoints (docs/protocol.md section 2), from the kept evaluations"
    while IFS='|' read -r label base _; do
      [[ " ${dense[*]} " == *"/eval/$label/"* ]] || continue  # not evaluated (yet)
      echo
      "$CD" report "${dense[@]}" --metrics outcomes --compare "$label" "$base" </dev/null \
        | sed -n '/^## .* vs /,$p' || true
    done <<<"$ABLATIONS"
    if [[ ${#stopgo[@]} -gt 0 ]]; then
      echo
      "$CD" report "${stopgo[@]}" --metrics stopgo
      if [[ " ${stopgo[*]} " == *"-retrain/"* ]]; then
        echo
        echo "A label ending in -retrain is that method retrained (TRAIN=retrain; protocol section 11, session 39): the recipe, data folder and seed of its section-7 run, other weights, evaluated on these suites only."
      fi
    fi
  } > "$f.tmp"
  mv "$f.tmp" "$f"
  keep_file "$f"
}

run_step() {
  case $1 in
    tune | choose)
      if [[ $MODE == free ]]; then
        echo "error: MODE=free takes route mode's chosen configs ($CONFIGS): run $1 without MODE" >&2
        return 1
      fi
      $1 ;;
    data) data_step ;;
    train) train_step ;;
    eval) eval_step ;;
    ablations) ablations_step ;;
    secondary) secondary_step ;;
    probe) probe_step ;;
    gpu-list) gpu_list_step ;;
    report) report_step ;;
  esac
}

run_steps "tune choose data train eval ablations secondary probe gpu-list report" "$@"
