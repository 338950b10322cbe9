#!/usr/bin/env bash
# One round of expert takeover for the keypoint policy (issue 65, step 3), in stages that each leave what the
# next needs; every choice below was fixed on 2026-12-07 before any round's result (experiments/pusht/README.md).
#   bash experiments/pusht/takeover/round.sh K BASE rollouts|collect|train|judge
# K: the round (1, 2, ...). BASE: the policy being corrected (a pretrained_model folder).
#   rollouts  BASE on 100 of gym-pusht's resets of seed 13000 + K (never a judge's or a validation seed)
#   collect   the closed-loop expert from up to 4 stall states a rollout (improve/stalls.py); its replay list
#             lands in experiments/pusht/demos/takeover/rK.json (commit it)
#   train     BASE fine-tuned (--init_from: its weights, EMA and normalisation) on the position pool and every
#             takeover list so far, 5000 steps of 64 at the preset's lr; fp16 partials in
#             experiments/pusht/takeover/rK/partial (commit them while the stage is unfinished)
#   judge     BASE and the candidate by lerobot-eval, 100 episodes of the validation seed 12100 each
set -eu
cd "$(dirname "$0")/../../.."
K=$1 BASE=$2 STEP=$3
OUT=outputs/takeover/r$K
BIN=.venv/bin
mkdir -p experiments/pusht/demos/takeover "$OUT"
case $STEP in
rollouts)
  $BIN/gcs-push evaluate --env_id=gym_pusht/PushT-v0 --policies="[$BASE]" --num_initial_conditions=100 --runs=1 \
    --seed=$((13000 + K)) --videos=0 --workers=${WORKERS:-2} --output_dir=$OUT/rollouts ;;
collect)
  $BIN/gcs-push collect --rollouts="[$OUT/rollouts]" --max_per_run=4 --seed=$((13100 + K)) --workers=${WORKERS:-2} \
    --repo_id=local/gcs_pusht_takeover_r$K --root=$OUT/data --resume=true
  cp $OUT/data/meta/gcs_push_replay.json experiments/pusht/demos/takeover/r$K.json ;;
train)
  P=experiments/pusht/demos/position/seed480
  LISTS="${P}0.json,${P}1.json,${P}2.json,${P}3.json"
  for j in $(seq 1 $K); do LISTS="$LISTS,experiments/pusht/demos/takeover/r$j.json"; done
  $BIN/gcs-push train --config_path=configs/train/pusht_keypoints.json --init_from="$BASE" --data.episodes=null \
    --data.lists="[$LISTS]" --schedule.steps=5000 --output_dir=$OUT/train \
    --partial_dir=experiments/pusht/takeover/r$K/partial ;;
judge)
  for who in base candidate; do
    P=$BASE; [ $who = candidate ] && P=$OUT/train/pretrained_model
    [ -f $OUT/judge_$who/eval_info.json ] && continue
    HF_HUB_OFFLINE=1 $BIN/lerobot-eval --policy.path=$P --env.type=pusht --env.obs_type=environment_state_agent_pos \
      --eval.n_episodes=100 --eval.batch_size=10 --eval.use_async_envs=false --seed=12100 --policy.device=cpu \
      --output_dir=$OUT/judge_$who
  done ;;
*) echo "step: rollouts, collect, train or judge" >&2; exit 2 ;;
esac
