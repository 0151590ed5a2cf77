#!/usr/bin/env bash
# The study at the paper's demonstration count (docs/results/paper-count.md): one pair of TAX3D-CD arms trained side
# by side, one core each, on the paper's 500,000-step schedule; each call resumes both from runs/paper-count/.
#
#   bash scripts/paper_count.sh PAIR [HOURS]    # HOURS: stop both arms after this long, saving last/ (default 2)
#   bash scripts/paper_count.sh --list          # the pairs
#
# First the pair's demonstrations (the first 64 train and 40 val demos of the task, with both cores, skipped where
# present), then lab.studies.paper_count in a process group of its own at a lowered priority (autogroup nice 5),
# so that other work on the machine goes first; its curves are kept in docs/results/paper-count/PAIR.json.
set -euo pipefail
cd "$(dirname "$0")/.."
TAX3D=${TAX3D:-.venv/bin/tax3d}
PYTHON=${PYTHON:-.venv/bin/python}

# pair: task, data folder, then NAME "OPTIONS" of each arm
pair() {
  case $1 in
    unimodal-cpu-scene) ARMS=(cpu "" scene "--data.rotate-scene True"); TASK=hangproccloth-unimodal; DATA=unimodal;;
    # the paper's anchor rotation (App. B); the authors' scene rotation with the paper's DiT (128 x 5) and points
    unimodal-anchor-capacity) ARMS=(anchor "--data.rotate True"
                                    capacity "--data.rotate-scene True --model.hidden-size 128 --model.depth 5 --data.num-action-points 512 --data.num-anchor-points 512")
                              TASK=hangproccloth-unimodal; DATA=unimodal;;
    *) return 1;;
  esac
}

PAIRS="unimodal-cpu-scene unimodal-anchor-capacity"
if [ "${1:-}" = --list ]; then echo "$PAIRS"; exit 0; fi
NAME=${1:-}; HOURS=${2:-2}
pair "$NAME" || { echo "scripts/paper_count.sh: unknown pair '$NAME'; expected one of: $PAIRS" >&2; exit 2; }
mkdir -p runs/logs
for split in train val; do
  num=64; [ $split = val ] && num=40
  "$TAX3D" generate --task "$TASK" --split $split --num $num --out "data/$DATA/$split" --workers 2 \
    >> "runs/logs/paper-count-$NAME-data.log" 2>&1
done
args=(-m lab.studies.paper_count --task "$TASK" --train "data/$DATA/train" --num-train 64 --val "data/$DATA/val"
      --out "runs/paper-count/$DATA" --hours "$HOURS" --keep "docs/results/paper-count/$NAME.json")
for ((i = 0; i < ${#ARMS[@]}; i += 2)); do args+=(--arm "${ARMS[i]}" "${ARMS[i + 1]}"); done
exec setsid bash -c 'echo 5 > /proc/$$/autogroup; exec "$@"' priority "$PYTHON" "${args[@]}"
