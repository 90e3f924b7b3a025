#!/usr/bin/env bash
# The MPI overhead (issue 35): episodes/s of one 50-episode suite evaluated under
# `eval --workers N` and under `mpirun -np N` (one world per rank), in one run, into fresh
# folders (each twice, the faster counts); prints one JSON line.
#   scripts/bench_mpi.sh [N]                    N processes (default 2)
#   AGENT=bc-oh CHECKPOINT=RUN CONFIG=C scripts/bench_mpi.sh   another agent (default: expert,
#                                               whose cheap episodes are MPI's worst case)
set -euo pipefail
cd "$(dirname "$0")/.."
CD=${CD:-build/causaldrive}
N=${1:-2}
DIR=$(mktemp -d /tmp/cd-bench-mpi.XXXXXX)
trap 'rm -rf "$DIR"' EXIT
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
export OMPI_MCA_btl_vader_single_copy_mechanism=none OMP_NUM_THREADS=1
"$CD" suite --town town-a --traffic regular --tasks 25 --trials 2 --seed 35 --min-route 300 \
  --max-route 700 --scenarios route red_light leader --out "$DIR/suite.json" >/dev/null
timed() {  # LABEL CMD... -> milliseconds
  local t0 t1
  t0=$(date +%s%N)
  "${@:2}" >"$DIR/$1.log" 2>&1 || { cat "$DIR/$1.log" >&2; exit 1; }
  t1=$(date +%s%N)
  echo $(( (t1 - t0) / 1000000 ))
}
AGENT=${AGENT:-expert}
args=(eval --agent "$AGENT" --suite "$DIR/suite.json" --quiet)
[[ -n ${CHECKPOINT:-} ]] && args+=(--checkpoint "$CHECKPOINT")
[[ -n ${CONFIG:-} ]] && args+=(--config "$CONFIG")
# Each launcher twice, alternating, into fresh folders; the faster of each pair counts (the
# machine's other load only ever slows a run down).
best() { (( $1 < $2 )) && echo "$1" || echo "$2"; }
w=999999999 m=999999999
for rep in 1 2; do
  w=$(best "$w" "$(timed workers$rep "$CD" "${args[@]}" --workers "$N" --out "$DIR/workers$rep")")
  m=$(best "$m" "$(timed mpi$rep mpirun --oversubscribe -np "$N" "$CD" "${args[@]}" --workers 1 \
                   --out "$DIR/mpi$rep")")
done
cmp -s "$DIR/workers1/results.json" "$DIR/mpi1/results.json" && same=true || same=false
python3 - "$N" "$w" "$m" "$same" "$AGENT" <<'PY'
import json, sys
n, w, m, same = int(sys.argv[1]), float(sys.argv[2]) / 1e3, float(sys.argv[3]) / 1e3, sys.argv[4] == "true"
print(json.dumps({"agent": sys.argv[5], "episodes": 50, "processes": n, "workers_s": round(w, 2), "mpi_s": round(m, 2),
                  "workers_episodes_per_s": round(50 / w, 3), "mpi_episodes_per_s": round(50 / m, 3),
                  "mpi_overhead_pct": round(100 * (m - w) / w, 2), "same_results": same}))
PY
