#!/usr/bin/env bash
# The paper's table (docs/results/table/TASK/NUM/ROW.json): every row not yet kept, two at a time, one core each.
#
#   bash scripts/table.sh                  # all missing rows, in the order below
#   bash scripts/table.sh hangbag ...      # the named tasks' rows only, in that order
#   bash scripts/table.sh --dry-run [...]  # only print their commands
#
# Each row is one `tax3d table` command (60 minutes of training on one core, its weights chosen on val, its
# test episodes scored once); a killed row resumes from runs/table/.../last when run again. First the demonstrations
# of every named task's missing rows, made with both cores while nothing trains (data/<folder>, skipped where
# present; a task whose demonstrations fail waits for the next start), then all those rows in one stream, two at a
# time: no demonstration is made beside a training row, and a task with an odd number of rows shares its last pair
# with the next task's first row instead of idling a core.
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

missing() {  # task num: the task's rows without kept JSON, one a line
  echo "$ROWS" | while read -r task num folder rows; do
    [ "$task $num" = "$1 $2" ] || continue
    for row in $rows; do
      [ -f "docs/results/table/$task/$num/$row.json" ] || echo "$row"
    done
  done
}

table() {  # task num folder row: the row's command, as its kept JSON records it (rows kept before: `tax3d benchmark`)
  echo "table --task $1 --variants $4 --num-train $2 --minutes $MINUTES --data data/$3 --out runs/table/$1-$2" \
    "--keep docs/results/table/$1/$2 --workers 1"
}

data() {  # task num folder rows: the demonstrations of the task's rows (comma-separated), with both cores
  "$TAX3D" table --task "$1" --variants "$4" --num-train "$2" --data "data/$3" --out "runs/table/$1-$2" \
    --workers 2 --data-only
}

row() {  # task num folder row
  local log=runs/logs/$1-$2-$4.log
  echo "$(date -u +%FT%TZ) start $*"
  # shellcheck disable=SC2046  # the command's words hold no spaces
  "$TAX3D" $(table "$@") >> "$log" 2>&1 && echo "$(date -u +%FT%TZ) done $*" \
    || echo "$(date -u +%FT%TZ) FAILED $* (see $log)"
}

tasks() {  # task num folder: the named tasks in their order, or every task in the order above
  local all
  all=$(echo "$ROWS" | while read -r task num folder _; do [ -z "$task" ] || echo "$task $num $folder"; done)
  [ $# -gt 0 ] || { echo "$all"; return; }
  for name in "$@"; do
    grep "^$name " <<< "$all" || { echo "scripts/table.sh: unknown task '$name'; expected one of:" \
      $(cut -d' ' -f1 <<< "$all" | sort -u) >&2; return 2; }
  done
}

DRY=; [ "${1:-}" = --dry-run ] && { DRY=1; shift; }
TASKS=$(tasks "$@") || exit 2
if [ -n "$DRY" ]; then
  echo "$TASKS" | while read -r task num folder; do
    missing "$task" "$num" | while read -r r; do echo "tax3d $(table "$task" "$num" "$folder" "$r")"; done
  done
  exit 0
fi
mkdir -p runs/logs data
exec 9> runs/.table.lock
flock -n 9 || { echo "scripts/table.sh: another queue holds runs/.table.lock; expected one at a time" >&2; exit 2; }
export TAX3D MINUTES
export -f row table
READY=$(echo "$TASKS" | while read -r task num folder; do  # the tasks whose demonstrations are all made
  rows=$(missing "$task" "$num" | paste -sd, -)
  [ -n "$rows" ] || continue
  echo "$(date -u +%FT%TZ) data $task $num $folder ($rows)" >&2
  if data "$task" "$num" "$folder" "$rows" >> "runs/logs/$task-$num-data.log" 2>&1 </dev/null; then
    echo "$task $num $folder"
  else  # its rows wait for the next start; the other tasks' rows go on
    echo "$(date -u +%FT%TZ) FAILED data $task $num, its rows skipped (see runs/logs/$task-$num-data.log)" >&2
  fi
done)
[ -n "$READY" ] || exit 1
echo "$READY" | while read -r task num folder; do
  missing "$task" "$num" | sed "s|^|$task $num $folder |"
done | xargs -P 2 -L 1 bash -c 'row "$@"' row
