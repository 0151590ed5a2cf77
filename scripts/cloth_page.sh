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
  f=$E/$TASK-${v%%:*}.json; [ -f $f ] || f=$E/$TASK-short-${v%%:*}.json
  [ -f $f ] && ARGS+=("${v##*:}=$f")
done
for v in cd:CD cp:CP; do  # TAX3D at the ablations' short budget, for a like-for-like comparison
  f=$E/$TASK-short-${v%%:*}.json; [ -f $f ] && ARGS+=("TAX3D-${v##*:} at the ablations' 900 steps=$f")
done
B=()
[ -f $E/$TASK-demo-goal.json ] && B+=("each demo's own goal (the policy's ceiling)=$E/$TASK-demo-goal.json")
[ -f $E/$TASK-mean-goal.json ] && B+=("mean goal of train in the anchor frame (the floor)=$E/$TASK-mean-goal.json")
EXTRA=()
[ -f $E/$TASK-dp3.json ] && EXTRA+=(--train-command "DP3, its \`cpu\` preset cut to 1,500 steps, alone on this CPU, evaluated like the others but with one action sequence per step :: tax3d train-dp3 --preset cpu --steps 1500 --data data/$TASK/train --task hangproccloth-$TASK --out runs/$TASK-dp3 && tax3d eval --checkpoint runs/$TASK-dp3/last --task hangproccloth-$TASK --data data/$TASK --splits train,unseen,ood --episodes 20 --workers 2 --out runs/eval-$TASK-dp3")
[ -f $E/$TASK-demo-goal.json ] && EXTRA+=(--train-command "the policy's ceiling, each demo's own goal, on the first 10 episodes of each split :: python scripts/oracle_policy.py --task hangproccloth-$TASK --data data/$TASK --goal demo --episodes 10 --workers 2 --out docs/results/evals/$TASK-demo-goal.json")
[ -f $E/$TASK-mean-goal.json ] && EXTRA+=(--train-command "the mean-goal floor :: python scripts/oracle_policy.py --task hangproccloth-$TASK --data data/$TASK --goal mean --episodes 20 --workers 2 --out docs/results/evals/$TASK-mean-goal.json")
if compgen -G "$E/$TASK-short-*.json" > /dev/null; then
  EXTRA+=(--train-command "the ablations V (sd, sp, cd_w, cp_w, cd_nac, cp_nac) and TAX3D-CD / CP again, all at a short budget of 900 steps (the cosine schedule completed), two side by side on this CPU; evaluated on the first 10 episodes of each split :: tax3d train --preset cpu --model.variant V --data.train data/$TASK/train --data.val data/$TASK/unseen --data.task hangproccloth-$TASK --train.steps 900 --train.time-limit 8 --out runs/$TASK-short-V && tax3d eval --checkpoint runs/$TASK-short-V/best --task hangproccloth-$TASK --data data/$TASK --splits train,unseen,ood --episodes 10 --samples 20 --steps 10 --workers 2 --out runs/eval-$TASK-short-V")
fi
TRAIN=()
case $TASK in
  unimodal) TRAIN+=(--train-command "TAX3D-CD and TAX3D-CP, \`cpu\` preset, the two side by side on this 2-core CPU (one thread each), stopped by the 22-minute limit :: tax3d train --preset cpu --model.variant V --data.train data/$TASK/train --data.val data/$TASK/unseen --data.task hangproccloth-$TASK --train.steps 4000 --train.time-limit 22 --out runs/$TASK-V");;
  multimodal) TRAIN+=(--train-command "TAX3D-CD and TAX3D-CP, \`cpu\` preset, the two side by side on this 2-core CPU (one thread each), stopped by the 15-minute limit :: tax3d train --preset cpu --model.variant V --data.train data/$TASK/train --data.val data/$TASK/unseen --data.task hangproccloth-$TASK --train.steps 4000 --train.time-limit 15 --out runs/$TASK-V"
    --train-command "RD and RP, the same but a 10-minute limit (one regression pass per step) :: tax3d train --preset cpu --model.variant V --data.train data/$TASK/train --data.val data/$TASK/unseen --data.task hangproccloth-$TASK --train.steps 4000 --train.time-limit 10 --out runs/$TASK-V");;
esac
[ $TASK = simple ] || TRAIN+=(--train-command "evaluation of each TAX3D variant, the first 20 episodes of each split, 20 goal samples per episode with the 10-step sampler (the policy executes the first sample) :: tax3d eval --checkpoint runs/$TASK-V/best --task hangproccloth-$TASK --data data/$TASK --splits train,unseen,ood --episodes 20 --samples 20 --steps 10 --workers 2 --out runs/eval-$TASK-V && python scripts/keep_summary.py runs/eval-$TASK-V docs/results/evals/$TASK-V.json")
[ -f $E/$TASK-mode-spread.json ] && EXTRA+=(--mode-spread $E/$TASK-mode-spread.json)
NOTES=()
[ -f docs/results/$TASK-notes.md ] && NOTES+=(--note "$(cat docs/results/$TASK-notes.md)")
python scripts/task_report.py "${ARGS[@]}" ${B:+--baseline "${B[@]}"} --plot "${NOTES[@]}" \
  --train-command "demonstrations ($NUM_TRAIN for train, the first 20 of the paper's 40 for unseen and ood), S = unseen, ood; train also records the per-step trajectories DP3 learns from; the expert failed every attempt on one multimodal training cloth, so that split has 62 :: tax3d generate --task hangproccloth-$TASK --split train --num $NUM_TRAIN --trajectories --out data/$TASK/train --workers 2 && tax3d generate --task hangproccloth-$TASK --split S --num 20 --out data/$TASK/S --workers 2" \
  "${TRAIN[@]}" \
  "${EXTRA[@]}" "$@"
