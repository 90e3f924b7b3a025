#!/usr/bin/env bash
# Reproduces seed 001's driving tables (appendix B: tables 7-11 and the branches ablation) on
# causaldrive's towns with configs/residual_paper.toml.
#
#   scripts/residual_paper.sh train     # town-a expert data + the seven methods, all seeds
#   scripts/residual_paper.sh train-ablations  # two-stream bc-oh/keyframe, residual 2 and 4 branches
#   scripts/residual_paper.sh table7    # failure modes, training town (town-a regular, dense)
#   scripts/residual_paper.sh table8    # failure modes, new sensor (town-a, eval.sensor shifted)
#   scripts/residual_paper.sh table9    # failure modes, new town (town-b regular, dense)
#   scripts/residual_paper.sh stopgo    # stall rate, start delay: town-a-stopgo, town-b-stopgo
#   scripts/residual_paper.sh table10   # green-light rate, town-a dense (bc-oh, keyframe, residual)
#   scripts/residual_paper.sh table11   # two-stream bc-oh / keyframe vs one-stream, town-a dense
#   scripts/residual_paper.sh branches  # residual with 1, 2 and 4 memory branches, town-a dense
#   scripts/residual_paper.sh probe     # copycat probe of every history method (JSON per run)
#   scripts/residual_paper.sh diagnose  # what each run learned, situation by situation, on its
#                                       # held-out episodes (JSON per run, diagnose.md)
#   scripts/residual_paper.sh families  # seed 000's cim trained on the same data, next to
#                                       # bc-oh, keyframe and residual (failure modes, A and B)
#   scripts/residual_paper.sh all       # everything above in order
#
# Several steps run in order (`scripts/residual_paper.sh train table7 table9`);
# an unknown step is refused before any of them runs.
# Every step resumes: collect, train and eval skip what their output folders already hold, so
# an interrupted run is continued by running the same command again. Finished evaluations,
# probe reports and tables are also kept in results/residual_paper (committed; see
# scripts/paper_lib.sh): a kept result is not measured again. Environment knobs:
#   CD      the causaldrive binary        (default: build/causaldrive)
#   OUT     the experiment folder          (default: runs/residual_paper)
#   KEEP    the kept results               (default: results/residual_paper)
#   SEEDS   training seeds                 (default: "0 1 2")
#   TASKS   tasks per suite; 25 uses the built-in suites (default: 25, as the seed's NoCrash)
#   TRIALS  trials per task                (default: 1)
#   WORKERS evaluation workers             (default: 2)
#   CONFIG  the experiment config          (default: configs/residual_paper.toml)
#   METHODS the methods of train, table7-9, stopgo, probe and diagnose (default: all seven)
#   ABLATION_LABELS the runs of train-ablations (default: all four; table11 needs the two
#           two-stream ones, branches the residual-b2 and -b4 ones)
set -euo pipefail

cd "$(dirname "$0")/.."
CD=${CD:-build/causaldrive}
CONFIG=${CONFIG:-configs/residual_paper.toml}
OUT=${OUT:-runs/residual_paper}
SEEDS=${SEEDS:-"0 1 2"}
TASKS=${TASKS:-25}
TRIALS=${TRIALS:-1}
WORKERS=${WORKERS:-2}
DATA=$OUT/data/town-a
METHODS=${METHODS:-"bc-so bc-oh residual dagger hd fca keyframe"}
source scripts/paper_lib.sh

# Ablations: label, method and the [residual] table appended to the paper config.
ABLATIONS=(
  "two-stream-bc-oh|residual|policy_input = \"history\"\nmemory_target = \"action\""
  "two-stream-keyframe|residual|policy_input = \"history\"\nmemory_target = \"action\"\nweights = \"keyframe\""
  "residual-b2|residual|branches = 2"
  "residual-b4|residual|branches = 4"
)

ablation_config() {  # LABEL -> a config file: the paper config plus the ablation's table
  local label=$1 entry
  for entry in "${ABLATIONS[@]}"; do
    IFS='|' read -r name method table <<<"$entry"
    if [[ $name == "$label" ]]; then
      mkdir -p "$OUT/configs"
      local file=$OUT/configs/$label.toml
      { cat "$CONFIG"; printf '\n[residual]\n%b\n' "$table"; } > "$file.tmp" && mv "$file.tmp" "$file"
      echo "$file"
      return
    fi
  done
  echo "unknown ablation $label" >&2
  exit 1
}

train_all() {
  "$CD" collect --config "$CONFIG" --out "$DATA"
  for s in $SEEDS; do
    local T=$OUT/train/seed$s
    for m in $METHODS; do
      kept_train "$T/$m" --config "$CONFIG" --method "$m" --data "$DATA" --seed "$s"
    done
  done
}

ABLATION_LABELS=${ABLATION_LABELS:-"two-stream-bc-oh two-stream-keyframe residual-b2 residual-b4"}

train_ablations() {
  local label
  for label in $ABLATION_LABELS; do ablation_config "$label" >/dev/null; done  # names checked first
  for s in $SEEDS; do
    local T=$OUT/train/seed$s
    for entry in "${ABLATIONS[@]}"; do
      IFS='|' read -r label method _ <<<"$entry"
      [[ " $ABLATION_LABELS " == *" $label "* ]] || continue
      kept_train "$T/$label" --config "$(ablation_config "$label")" --method "$method" \
        --data "$DATA" --seed "$s"
    done
  done
}

probe_all() {
  for s in $SEEDS; do
    for m in $METHODS; do
      [[ $m == bc-so ]] && continue  # no history to probe
      kept_json "$OUT/probe/seed$s/$m.json" "$CD" probe --checkpoint "$OUT/train/seed$s/$m" \
        --data "$DATA" --max-frames 2000 --json
    done
  done
  python3 - "$KEEP/probe" "$SEEDS" > "$OUT/probe.md" <<'PY'
import json, os, sys, statistics as st
root, seeds = sys.argv[1], sys.argv[2].split()
print("| method | history effect, path free | history effect, blocked |")
print("|---|---|---|")
for m in ["bc-oh", "residual", "dagger", "hd", "fca", "keyframe"]:
    row = []
    for group in ["path_free", "blocked"]:
        v = [json.load(open(f"{root}/seed{s}/{m}.json"))[group]["history_effect"] for s in seeds
             if os.path.exists(f"{root}/seed{s}/{m}.json")]  # methods not probed yet: "-"
        v = [x for x in v if x is not None]
        sd = st.stdev(v) if len(v) > 1 else 0.0
        row.append(f"{st.mean(v):.3f} ± {sd:.3f}" if v else "-")
    print(f"| {m} | {row[0]} | {row[1]} |")
PY
  keep_file "$OUT/probe.md"
  cat "$OUT/probe.md"
}

diagnose_all() {
  for s in $SEEDS; do
    for m in $METHODS; do
      local run=$OUT/train/seed$s/$m report=$OUT/diagnose/seed$s/$m.json
      if [[ ! -f $(kept_of "$report") ]]; then
        restore_run "$run" || return
        [[ -f $run/best.pt ]] || {
          echo "diagnose: $run has no best.pt (weights over 5 MB are not kept: train it first); skipped" >&2
          continue
        }
      fi
      kept_json "$report" "$CD" diagnose --checkpoint "$run" --data "$DATA" --json
    done
  done
  # shellcheck disable=SC2086
  scripts/diagnose_table.py "$KEEP/diagnose" --seeds $SEEDS --methods $METHODS > "$OUT/diagnose.md"
  keep_file "$OUT/diagnose.md"
  cat "$OUT/diagnose.md"
}

A="town-a-regular town-a-dense"
B="town-b-regular town-b-dense"
run_step() {
  case $1 in
    train) train_all ;;
    train-ablations) train_ablations ;;
    table7) eval_agents table7 failure,lights clean "$A" $METHODS ;;
    table8) eval_agents table8 failure shifted "$A" $METHODS ;;
    table9) eval_agents table9 failure clean "$B" $METHODS ;;
    stopgo) eval_agents stopgo stopgo,outcomes clean "town-a-stopgo town-b-stopgo" $METHODS ;;
    table10) eval_agents table10 lights clean town-a-dense bc-oh keyframe residual ;;
    table11) eval_agents table11 outcomes clean town-a-dense two-stream-bc-oh=residual \
               two-stream-keyframe=residual bc-oh keyframe residual ;;
    branches) eval_agents branches outcomes clean town-a-dense residual residual-b2=residual \
                residual-b4=residual ;;
    probe) probe_all ;;
    diagnose) diagnose_all ;;
    families)
      for s in $SEEDS; do
        kept_train "$OUT/train/seed$s/cim" --config configs/cim_paper.toml --method cim \
          --data "$DATA" --seed "$s"
      done
      eval_agents families failure clean "$A $B" bc-oh keyframe residual cim
      ;;
    all)
      for step in train train-ablations table7 table8 table9 stopgo table10 table11 branches \
        probe diagnose families; do
        run_step "$step"
      done
      ;;
  esac
}

run_steps "train train-ablations table7 table8 table9 stopgo table10 table11 branches probe diagnose families all" "$@"
