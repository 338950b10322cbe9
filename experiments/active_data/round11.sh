#!/usr/bin/env bash
# Active data, round 11. Every step resumes after a kill (re-run the script; delete a half-written merge
# folder first). Settings and rule fixed before any round-11 step ran (session 19, 17:20), aimed at the one
# target left, mean success time on the hard set (round 10b: 1.22x GCS's, two goal-side initial conditions
# at 1.9x):
#   - base B: round 10b (shipped);
#   - rollouts of B, 1 run each, with and without disturbances, on 80 hard initial conditions (seed 4090,
#     20 of each family) and 20 uniform ones (seed 4091): round 10's mix;
#   - collect with --large_regret_m=0.25, as round 10 (a successful run's 0.25-0.5 m detours are branched
#     from, as a failed run's are);
#   - training data: the base demonstrations plus every round's states (rounds 1, 2, 4-11);
#   - fine-tune B for 2500 steps of batch 32 (round 10b's schedule: round 10's 1500 steps lengthened the
#     path, 2500 shortened it, 2000 more did not help), bf16, peak lr 1e-4, seed 8013; step 2500 is the
#     one evaluated;
#   - rule (round 10b's): on an eleventh validation set no one has looked at, 40 hard (seed 5025) and 40
#     uniform (seed 5026) initial conditions x 3 runs, no disturbances, 60 s, round 11 replaces round 10b
#     only with at least 3 more successes over the 240 runs, or, within 2 either way, a mean simulation time
#     of the successful runs at least 5% lower (validation_winner.py --margin=3 --time_gain=0.05). Then the
#     test sets (seeds 1000, 2000, 3000) run beside round 10b, whose rows are copied from
#     results/active_round10b_*, and it ships whatever they give.
set -euo pipefail
export HF_HUB_OFFLINE=1
C=~/.cache/huggingface/lerobot/local
E=experiments/active_data

commit() {  # commit PATH MESSAGE, waiting for another git process to let go of the index
    while [ -f .git/index.lock ]; do sleep 5; done
    git add "$1" && git commit -q -m "$2" -- "$1" || true
}

B=$E/round10b/active_step2500
R11=$E/round11/active_step2500
mkdir -p $E/round11

# Steps 0-4 make the weights; once they are committed, the script goes straight to step 5.
if [ ! -f $R11/model.safetensors ]; then

# 0. The data earlier rounds trained on, rebuilt from what git keeps.
[ -f $C/gcs_push_box_1000/meta/info.json ] || \
    .venv/bin/gcs-push generate --episodes=1000 --repo_id=local/gcs_push_box_1000 --workers=2 --resume=true
for r in 1 2 4 5 6 7 8 9 10; do
    [ -f $C/gcs_push_r${r}_active/meta/info.json ] && continue
    n=$(.venv/bin/python -c "import json; print(len(json.load(open('$E/round$r/branch_states.json'))))")
    .venv/bin/gcs-push generate --expert=closed-loop --initial_conditions=$E/round$r/branch_states.json \
        --episodes=$n --repo_id=local/gcs_push_r${r}_active --workers=2 --resume=true
done
[ "${STOP_AFTER_REBUILD:-0}" = 1 ] && exit 0

# 1. Rollouts of B, with regret.
.venv/bin/gcs-push evaluate --policies=[$B] --disturbances=true --sampler=hard --seed=4090 \
    --num_initial_conditions=80 --runs=1 --timeout_s=60 --workers=2 --videos=0 --output_dir=$E/round11/rollouts_hard
.venv/bin/gcs-push evaluate --policies=[$B] --disturbances=true --sampler=uniform --seed=4091 \
    --num_initial_conditions=20 --runs=1 --timeout_s=60 --workers=2 --videos=0 --output_dir=$E/round11/rollouts_uniform
commit $E/round11 "Round 11 step 1: rollouts of round 10b"

# 2. Branch states labelled by the closed-loop expert.
.venv/bin/gcs-push collect --rollouts=[$E/round11/rollouts_hard,$E/round11/rollouts_uniform] \
    --large_regret_m=0.25 --repo_id=local/gcs_push_r11_active --workers=2 --resume=true
cp $C/gcs_push_r11_active.branch_states.json $E/round11/branch_states.json
commit $E/round11 "Round 11 step 2: branch states"
[ "${STOP_AFTER_COLLECT:-0}" = 1 ] && exit 0

# 3. Merge with LeRobot's aggregation.
if [ ! -f $C/gcs_push_r11_merged/meta/info.json ]; then
    rm -rf $C/gcs_push_r11_merged
    .venv/bin/lerobot-edit-dataset --new_repo_id local/gcs_push_r11_merged --operation.type merge \
        --operation.repo_ids "['local/gcs_push_box_1000', 'local/gcs_push_r1_active', 'local/gcs_push_r2_active', 'local/gcs_push_r4_active', 'local/gcs_push_r5_active', 'local/gcs_push_r6_active', 'local/gcs_push_r7_active', 'local/gcs_push_r8_active', 'local/gcs_push_r9_active', 'local/gcs_push_r10_active', 'local/gcs_push_r11_active']"
fi
[ "${STOP_AFTER_MERGE:-0}" = 1 ] && exit 0

# 4. Fine-tune B (resume a killed run with --resume=true --config_path=<its train_config.json>).
OMP_NUM_THREADS=2 .venv/bin/lerobot-train --config_path=configs/policy/diffusion_cpu.json \
    --policy.path=$B --dataset.repo_id=local/gcs_push_r11_merged \
    --output_dir=outputs/train/r11_active --job_name=r11_active --steps=2500 --save_freq=500 \
    --policy.use_amp=true --policy.optimizer_lr=1e-4 --seed=8013 --num_workers=1
.venv/bin/python -c "from lerobot_gcs_push.checkpoints import export_policy; export_policy('outputs/train/r11_active/checkpoints/002500/pretrained_model', '$R11')"
commit $E/round11 "Round 11: step 2500 weights (fp16), fine-tuned from round 10b; not yet evaluated"

fi  # steps 0-4

# 5. The eleventh validation set.
for v in "hard 5025" "uniform 5026"; do
    set -- $v
    .venv/bin/gcs-push evaluate --policies=[gcs-open-loop,$B,$R11] \
        --sampler=$1 --seed=$2 --num_initial_conditions=40 --runs=3 --timeout_s=60 --workers=2 --videos=0 \
        --output_dir=results/selection_$1_seed$2
done
.venv/bin/python experiments/scripts/hard_families.py results/selection_hard_seed5025
[ "${STOP_AFTER_VALIDATION:-0}" = 1 ] && exit 0

# 6. The rule, then the test sets for a new policy beside GCS and B, whose rows are copied.
winner=$(.venv/bin/python experiments/scripts/validation_winner.py --margin=3 --time_gain=0.05 $B $R11 \
    results/selection_hard_seed5025 results/selection_uniform_seed5026)
echo "by the rule: $winner"
[ "$winner" = "$R11" ] || exit 0
KEEP="\"policy\": \"(gcs-open-loop|gcs-closed-loop|$B)\""
for s in seed1000 seed2000 hard; do
    mkdir -p results/active_round11_$s
    [ -f results/active_round11_$s/runs.jsonl ] || grep -E "$KEEP" results/active_round10b_$s/runs.jsonl > results/active_round11_$s/runs.jsonl
done
.venv/bin/gcs-push evaluate --policies=[gcs-open-loop,$B,$R11] --disturbances=true \
    --seed=1000 --num_initial_conditions=20 --runs=5 --timeout_s=60 --workers=2 --videos=1 \
    --output_dir=results/active_round11_seed1000
.venv/bin/gcs-push evaluate --policies=[gcs-open-loop,gcs-closed-loop,$B,$R11] \
    --disturbances=true --seed=2000 --num_initial_conditions=20 --runs=5 --timeout_s=60 --workers=2 --videos=1 \
    --output_dir=results/active_round11_seed2000
.venv/bin/gcs-push evaluate --policies=[gcs-open-loop,gcs-closed-loop,$B,$R11] \
    --disturbances=true --sampler=hard --seed=3000 --num_initial_conditions=20 --runs=5 --timeout_s=60 \
    --workers=2 --videos=1 --output_dir=results/active_round11_hard
.venv/bin/python experiments/scripts/hard_families.py results/active_round11_hard
