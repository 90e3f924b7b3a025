#!/usr/bin/env bash
# Reproduces seed 001's MuJoCo-Image experiments (appendix C: table 13 and the main paper's
# MuJoCo comparison) with configs/mujoco_paper.toml: expert data per env, the seven methods x
# env x seed, closed-loop returns, and one table with the expert and a random policy for scale.
#
#   scripts/mujoco_paper.sh experts  # a SAC state expert per env (experts/ENV.pt, train-expert)
#   scripts/mujoco_paper.sh data     # expert episodes per env (the SAC experts; [mujoco.episodes])
#   scripts/mujoco_paper.sh train    # bc-so bc-oh residual fca keyframe hd dagger, every env x seed
#   scripts/mujoco_paper.sh eval     # every trained run, the expert and a random policy
#   scripts/mujoco_paper.sh table    # return and copycat R2, mean +- sd over seeds -> table.md/.csv;
#                                    # residual's IQM return against bc-oh's and keyframe's with
#                                    # intervals -> table13-compare.md
#   scripts/mujoco_paper.sh all      # the five in order
#   scripts/mujoco_paper.sh lr-sweep # table 12's learning rate: bc-oh at 0.1 ... 1e-4 on the first
#                                    # env's data, validation loss on its held-out episodes
#
# Several steps run in order (`scripts/mujoco_paper.sh data train eval table`);
# an unknown step is refused before any of them runs.
# Every step resumes: train-expert continues from its .resume file; collect, train and eval
# keep what their output folders already hold, so an interrupted run is continued by running
# the same command again; finished evaluations and
# the table are also kept in results/mujoco_paper (committed, scripts/paper_lib.sh). Knobs:
#   CD       the causaldrive binary    (default: build/causaldrive)
#   OUT      the experiment folder      (default: runs/mujoco_paper)
#   KEEP     the kept results           (default: results/mujoco_paper)
#   ENVS     environments               (default: "halfcheetah reacher hopper ant humanoid")
#   SEEDS    training seeds             (default: "0 1 2")
#   METHODS  methods                    (default: "bc-so bc-oh residual fca keyframe hd dagger")
#   CONFIG   the experiment config      (default: configs/mujoco_paper.toml)
#   SWEEP_EPOCHS  epochs per rate in lr-sweep (default: 20, the table's)
#   EXPERTS  the folder of SAC experts  (default: experts; kept when the file exists)
# With the SAC experts, training them is the costly part (about 40 min per 200k steps on 2
# cores); the planner (the config without expert_policies) costs ~0.04 s (halfcheetah) to ~0.6 s
# (humanoid) per step for data, dagger's rounds and the expert row alike.
set -euo pipefail

cd "$(dirname "$0")/.."
CD=${CD:-build/causaldrive}
OUT=${OUT:-runs/mujoco_paper}
ENVS=${ENVS:-"halfcheetah reacher hopper ant humanoid"}
SEEDS=${SEEDS:-"0 1 2"}
METHODS=${METHODS:-"bc-so bc-oh residual fca keyframe hd dagger"}
CONFIG=${CONFIG:-configs/mujoco_paper.toml}
source scripts/paper_lib.sh

# SAC env steps per env: ~12 ms each on 2 cores (one update per step), so ~40 min per 200k.
expert_steps() {
  case $1 in
    reacher) echo 50000 ;;
    halfcheetah | hopper) echo 200000 ;;
    ant) echo 300000 ;;
    *) echo 700000 ;;  # humanoid: 340-1000 from 60k to 640k steps, 1794 at 670k (experts/humanoid.json)
  esac
}

experts() {
  local dir=${EXPERTS:-experts}
  for env in $ENVS; do
    [[ -f $dir/$env.pt && ! -f $dir/$env.pt.resume ]] && { echo "$dir/$env.pt: kept" >&2; continue; }
    "$CD" train-expert --env "$env" --out "$dir/$env.pt" --steps "$(expert_steps "$env")" \
      --eval-episodes 3 --threads 2 --seed 0
  done
}

data() {
  for env in $ENVS; do
    "$CD" collect --env "$env" --config "$CONFIG" --out "$OUT/data/$env"
  done
}

train() {
  for env in $ENVS; do
    for s in $SEEDS; do
      for m in $METHODS; do
        "$CD" train --config "$CONFIG" --method "$m" --data "$OUT/data/$env" --seed "$s" \
          --out "$OUT/train/$env/seed$s/$m"
      done
    done
  done
}

evaluate() {
  for env in $ENVS; do
    for agent in expert random; do
      kept_eval "$OUT/eval/$env/$agent" --env "$env" --config "$CONFIG" --agent "$agent" --quiet
    done
    for s in $SEEDS; do
      for m in $METHODS; do
        local run=$OUT/train/$env/seed$s/$m
        [[ -f $KEEP/eval/$env/seed$s/$m/results.json ]] && continue
        [[ -f $run/checkpoint.json ]] || { echo "skipping $run: not trained" >&2; continue; }
        kept_eval "$OUT/eval/$env/seed$s/$m" --env "$env" --config "$CONFIG" --agent "$m" \
          --checkpoint "$run" --quiet
      done
    done
  done
}

lr_sweep() {
  local env=${ENVS%% *}
  mkdir -p "$OUT/configs"
  for lr in 0.1 0.01 0.001 0.0001; do
    local cfg=$OUT/configs/lr-$lr.toml
    sed "s/^lr = .*/lr = $lr/" "$CONFIG" > "$cfg.tmp" && mv "$cfg.tmp" "$cfg"
    "$CD" train --config "$cfg" --method bc-oh --data "$OUT/data/$env" --epochs "${SWEEP_EPOCHS:-20}" \
      --out "$OUT/lr_sweep/$env/lr-$lr"
  done
  python3 - "$OUT/lr_sweep/$env" <<'PY' | tee "$OUT/lr_sweep/$env/sweep.md"
import glob, json, os, sys
print("| lr | best validation L2 | at epoch | last train L2 |")
print("|---|---|---|---|")
runs = sorted(glob.glob(os.path.join(sys.argv[1], "lr-*")), key=lambda d: -float(d.split("lr-")[-1]))
for d in runs:
    ck = json.load(open(os.path.join(d, "checkpoint.json")))
    print(f"| {d.split('lr-')[-1]} | {ck['best_loss']:.4f} | {ck['best_epoch']} | "
          f"{ck['metrics'][-1]['train_loss']:.4f} |")
PY
  keep_file "$OUT/lr_sweep/$env/sweep.md"
}

table() {
  kept_report table return "$KEEP/eval"
  # Table 13's claim, residual ahead: its IQM return against bc-oh's and keyframe's per env.
  local cmp=$OUT/table13-compare.md
  : > "$cmp.tmp"
  for other in bc-oh keyframe; do
    "$CD" report "$KEEP/eval" --compare residual "$other" --compare-metric iqm_return \
      | sed -n '/^## residual vs/,$p' >> "$cmp.tmp"
    echo >> "$cmp.tmp"
  done
  mv "$cmp.tmp" "$cmp"
  keep_file "$cmp"
}

run_step() {
  case $1 in
    experts) experts ;;
    data) data ;;
    train) train ;;
    eval) evaluate ;;
    table) table ;;
    all) for step in experts data train eval table; do run_step "$step"; done ;;
    lr-sweep) lr_sweep ;;
  esac
}

run_steps "experts data train eval table all lr-sweep" "$@"
