#!/usr/bin/env bash
# Regenerates docs/results/hangproccloth-TASK.md and its .png (TASK = unimodal or multimodal; simple: the page
# hangproccloth-simple-baselines.md with DP3, the ablations and the mean-goal floor) from the evaluation
# summaries kept in docs/results/evals/ (`scripts/keep_summary.py`) and the mean-goal JSON beside them. Rows whose
# summary is absent are left out. Extra arguments go to scripts/task_report.py (e.g. --note "...").
set -euo pipefail
cd "$(dirname "$0")/.."
TASK=${1:?usage: bash scripts/cloth_page.sh unimodal|multimodal|simple [task_report options]}
shift
case $TASK in
  unimodal|multimodal) PAGE=hangproccloth-$TASK; NUM_TRAIN=64;;
  simple) PAGE=hangproccloth-simple-baselines; NUM_TRAIN=16;;
  *) echo "error: task $TASK: expected unimodal, multimodal or simple" >&2; exit 2;;
esac
E=docs/results/evals
ARGS=(--task $PAGE --eval)
for v in cd:CD cp:CP rd:RD rp:RP cd_w:CD-W cp_w:CP-W cd_nac:CD-NAC cp_nac:CP-NAC sd:SD sp:SP dp3:DP3; do
  f=$E/$TASK-${v%%:*}.json; [ -f $f ] && ARGS+=("${v##*:}=$f")
done
B=()
[ -f $E/$TASK-mean-goal.json ] && B+=("mean goal of train in the anchor frame (the floor)=$E/$TASK-mean-goal.json")
NOTES=()
[ -f docs/results/$TASK-notes.md ] && NOTES+=(--note "$(cat docs/results/$TASK-notes.md)")
python scripts/task_report.py "${ARGS[@]}" ${B:+--baseline "${B[@]}"} --plot "${NOTES[@]}" \
  --train-command "demonstrations ($NUM_TRAIN for train, the first 20 of the paper's 40 for unseen and ood), S = unseen, ood; train also records the per-step trajectories DP3 learns from :: tax3d generate --task hangproccloth-$TASK --split train --num $NUM_TRAIN --trajectories --out data/$TASK/train --workers 2 && tax3d generate --task hangproccloth-$TASK --split S --num 20 --out data/$TASK/S --workers 2" \
  --train-command "TAX3D variants V (cd, cp$([ $TASK = multimodal ] && echo ', rd, rp')), \`cpu\` preset, two side by side on this 2-core CPU, one thread each :: tax3d train --preset cpu --model.variant V --data.train data/$TASK/train --data.val data/$TASK/unseen --data.task hangproccloth-$TASK --train.steps 4000 --train.time-limit 22 --out runs/$TASK-V" \
  --train-command "evaluation of each, 20 episodes per split, 20 goal samples per episode (the policy executes the first) :: tax3d eval --checkpoint runs/$TASK-V/best --task hangproccloth-$TASK --data data/$TASK --splits train,unseen,ood --episodes 20 --samples 20 --workers 2 --out runs/eval-$TASK-V && python scripts/keep_summary.py runs/eval-$TASK-V docs/results/evals/$TASK-V.json" \
  --train-command "DP3, its \`cpu\` preset (3,000 steps), on this CPU beside another training :: tax3d train-dp3 --preset cpu --data data/$TASK/train --task hangproccloth-$TASK --out runs/$TASK-dp3" \
  --train-command "the mean-goal floor :: python scripts/oracle_policy.py --task hangproccloth-$TASK --data data/$TASK --goal mean --episodes 20 --workers 2 --out docs/results/evals/$TASK-mean-goal.json" \
  "$@"
