#!/usr/bin/env bash
# The paper's table (docs/results/table/TASK/NUM/ROW.json): every row not yet kept, two at a time, one core each.
#
#   bash scripts/table.sh            # all missing rows, in the order below
#   bash scripts/table.sh --dry-run  # only print their commands
#
# Each row is one `tax3d benchmark` command (60 minutes of training on one core, its weights chosen on val, its
# test episodes scored once); a killed row resumes from runs/table/.../last when run again. A task's
# demonstrations are generated once, with both cores, before its first row (data/<folder>, skipped when present).
set -euo pipefail
cd "$(dirname "$0")/.."
TAX3D=${TAX3D:-.venv/bin/tax3d}
MINUTES=60

# task, training demos, data folder, rows: the headline rows, the fixed goals, then the ablations and DP3
ROWS="
hangproccloth-simple 16 simple cd cp floor ceiling cd_w cp_w dp3 cd_nac cp_nac sd sp
hangbag 16 hangbag cd cp floor ceiling cd_w cp_w dp3 cd_nac cp_nac sd sp
hangproccloth-unimodal 512 unimodal cd cp floor ceiling cd_w cp_w cd_nac cp_nac sd sp dp3
hangproccloth-unimodal 64 unimodal cd cp
hangproccloth-multimodal 512 multimodal cd cp floor ceiling cd_w cp_w rd rp cd_nac cp_nac sd sp dp3
hangproccloth-multimodal 64 multimodal cd cp
"

missing() {  # one line per row without kept JSON: task num folder row
  echo "$ROWS" | while read -r task num folder rows; do
    [ -n "$task" ] || continue
    for row in $rows; do
      [ -f "docs/results/table/$task/$num/$row.json" ] || echo "$task $num $folder $row"
    done
  done
}

data() {  # task num folder row: the row's demonstrations, made once with both cores before rows use one
  "$TAX3D" benchmark --task "$1" --variants "$4" --num-train "$2" --data "data/$3" --out "runs/table/$1-$2" \
    --workers 2 --data-only
}

benchmark() {  # task num folder row: the row's command, as its kept JSON records it
  echo "benchmark --task $1 --variants $4 --num-train $2 --minutes $MINUTES --data data/$3 --out runs/table/$1-$2" \
    "--keep docs/results/table/$1/$2 --workers 1"
}

row() {  # task num folder row
  local log=runs/logs/$1-$2-$4.log
  mkdir -p runs/logs data
  flock "data/.$3.lock" bash -c 'data "$@"' data "$@" >> "$log" 2>&1
  echo "$(date -u +%FT%TZ) start $*"
  # shellcheck disable=SC2046  # the command's words hold no spaces
  "$TAX3D" $(benchmark "$@") >> "$log" 2>&1 && echo "$(date -u +%FT%TZ) done $*" \
    || echo "$(date -u +%FT%TZ) FAILED $* (see $log)"
}

if [ "${1:-}" = --dry-run ]; then
  missing | while read -r line; do echo "tax3d $(benchmark $line)"; done
  exit 0
fi
export TAX3D MINUTES
export -f row data benchmark
missing | xargs -P 2 -L 1 bash -c 'row "$@"' row
