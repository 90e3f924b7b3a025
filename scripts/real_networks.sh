#!/usr/bin/env bash
# The expert (the teacher of every learner) on real road networks that sumo-tools ships: on each
# network a 12-task regular suite drawn by `causaldrive suite` (seed 7) in each mode, route and
# free, evaluated with traces, and one table of outcomes.
#
#   scripts/real_networks.sh            # results/real_networks/expert.md and .csv
#
# Networks (NETS, default "drt pasubio kuehne"):
#   drt      sumo-tools' game/DRT/osm.net.xml, an OpenStreetMap town (1943 edges, 15 lights)
#   pasubio  sumolib's RealWorld/pasubio, a district of Bologna (111 edges, 8 lights)
#   kuehne   sumo-tools' game/kuehne (24 edges, 12 lights)
#   bs, a10  game/bs3d and game/A10KW: their lights are the game's, programs whose last phase
#            lasts 1000 or 10000 s until a player switches program, so an ego waits at a red
#            light for good; not in the default list for that reason
# Knobs: CD (build/causaldrive), OUT (runs/real_networks), KEEP (results/real_networks),
# TASKS (12), WORKERS (2), SUMO_TOOLS (/usr/share/sumo/tools). Finished evaluations and the
# drawn suites are kept in $KEEP (scripts/paper_lib.sh) and not run again.
set -euo pipefail

cd "$(dirname "$0")/.."
CD=${CD:-build/causaldrive}
OUT=${OUT:-runs/real_networks}
TASKS=${TASKS:-12}
TRIALS=1
WORKERS=${WORKERS:-2}
NETS=${NETS:-"drt pasubio kuehne"}
TOOLS=${SUMO_TOOLS:-/usr/share/sumo/tools}
source scripts/paper_lib.sh

net_file() {  # NAME -> the network file
  case $1 in
    drt) echo "$TOOLS/game/DRT/osm.net.xml" ;;
    pasubio) echo "$TOOLS/sumolib/scenario/scenarios/RealWorld/pasubio/pasubio_buslanes.net.xml" ;;
    kuehne) echo "$TOOLS/game/kuehne/kuehne.net.xml" ;;
    bs) echo "$TOOLS/game/bs3d/bs.net.xml" ;;
    a10) echo "$TOOLS/game/A10KW/osm.net.xml" ;;
    *) echo "real_networks.sh: unknown network '$1' (drt pasubio kuehne bs a10)" >&2; return 1 ;;
  esac
}

for name in $NETS; do  # every name and file checked before anything runs
  file=$(net_file "$name")
  [[ -f $file ]] || { echo "real_networks.sh: $file not found (install sumo-tools)" >&2; exit 1; }
done

dirs=()
mkdir -p "$KEEP/suites"
for mode in route free; do
  config=$(mode_config "$mode")
  for name in $NETS; do
    suite=$KEEP/suites/real-$name-$mode-$TASKS.json
    [[ -f $suite ]] || "$CD" suite --config "$config" --name "real-$name" --town "$(net_file "$name")" \
      --traffic regular --tasks "$TASKS" --trials 1 --seed 7 --out "$suite" >&2
    kept_eval "$OUT/eval/expert-$mode/real-$name" --config "$config" --agent expert \
      --label "expert-$mode" --suite "$suite" --workers "$WORKERS" --trace --quiet
    dirs+=("$KEPT")
  done
done
kept_report expert outcomes,lateral "${dirs[@]}"
cat "$OUT/expert.md"
