#!/usr/bin/env bash
# Active data, round 2 (session 11): round 1 (policies/diffusion_cpu as of commit 7e0dd4d) -> round 2.
# Every step resumes after a kill (re-run the line; delete a half-written merge folder first).
# Settings fixed before any round-2 result was seen (written 16:25, session 11):
#   - rollouts of the round-1 policy on 30 hard initial conditions (seed 4010) and 20 uniform ones
#     (seed 4011, for the random sets' failures), 1 run each, with and without disturbances; both seeds
#     apart from every evaluation set (1000, 2000, 3000) and from round 1's (4000, 4002);
#   - collect with round 1's settings (regret 0.5 m; 0.25 m in failed runs; 5% of the rest; 12 per run);
#   - fine-tune round 1 for 1000 steps of batch 32, bf16, peak lr 1e-4, seed 8001, on the same 1000 base
#     demonstrations plus the round-2 states (round 1's active data is not regenerated: its rollouts were
#     lost with session 10's machine and would cost 25 min); step 1000 is the one evaluated (2000 were
#     planned; cut to 1000 at 16:55, before any round-2 step ran, because this session's machine trains
#     at 1.0 step/s, not session 10's 1.5, and 2000 steps would not leave time to evaluate);
#   - rule for the shipped policy: round 2 replaces policies/diffusion_cpu if its success at 0.1 m on the
#     hard set (seed 3000, 20 x 5, no disturbances, 60 s) is above round 1's 0.83 and on the protocol set
#     (seed 1000) at least round 1's 0.95; both results are reported whatever they are.
set -euo pipefail
export HF_HUB_OFFLINE=1
R=outputs/active/round2
C=~/.cache/huggingface/lerobot/local

# Round 1's weights under a name of their own (policies/diffusion_cpu changes when a round ships).
if [ ! -d outputs/policies/round1 ]; then
    mkdir -p outputs/policies && cp -r experiments/active_data/round1/active_step2000 outputs/policies/round1
fi

# The base data (round1.sh makes it; resumes if present).
[ -f $C/gcs_push_box_1000/meta/info.json ] || \
    .venv/bin/gcs-push generate --episodes=1000 --repo_id=local/gcs_push_box_1000 --workers=2 --resume=true

# 1. Rollouts with regret.
.venv/bin/gcs-push evaluate --policies=[outputs/policies/round1] --disturbances=true --sampler=hard --seed=4010 \
    --num_initial_conditions=30 --runs=1 --timeout_s=60 --workers=2 --videos=0 --output_dir=$R/rollouts_hard
.venv/bin/gcs-push evaluate --policies=[outputs/policies/round1] --disturbances=true --sampler=uniform --seed=4011 \
    --num_initial_conditions=20 --runs=1 --timeout_s=60 --workers=2 --videos=0 --output_dir=$R/rollouts_uniform

# 2. Branch states labelled by the closed-loop expert.
.venv/bin/gcs-push collect --rollouts=[$R/rollouts_hard,$R/rollouts_uniform] --repo_id=local/gcs_push_r2_active \
    --workers=2 --resume=true

# 3. Merge with LeRobot's aggregation.
if [ ! -f $C/gcs_push_r2_active_merged/meta/info.json ]; then
    rm -rf $C/gcs_push_r2_active_merged
    .venv/bin/lerobot-edit-dataset --new_repo_id local/gcs_push_r2_active_merged --operation.type merge \
        --operation.repo_ids "['local/gcs_push_box_1000', 'local/gcs_push_r2_active']"
fi

# 4. Fine-tune round 1 (resume a killed run with --resume=true --config_path=<its train_config.json>).
OMP_NUM_THREADS=2 .venv/bin/lerobot-train --config_path=configs/policy/diffusion_cpu.json \
    --policy.path=outputs/policies/round1 --dataset.repo_id=local/gcs_push_r2_active_merged \
    --output_dir=outputs/train/r2_active --job_name=r2_active --steps=1000 --save_freq=500 \
    --policy.use_amp=true --policy.optimizer_lr=1e-4 --seed=8001 --num_workers=1
.venv/bin/python -c "from lerobot_gcs_push.checkpoints import export_policy; export_policy('outputs/train/r2_active/checkpoints/001000/pretrained_model', 'experiments/active_data/round2/active_step1000')"

# 5. Evaluate on the hard set beside GCS and round 1. The GCS and round-1 rows are round 1's own
#    (results/active_round1_hard, same seeds; a record does not depend on when or where it ran), copied so
#    that the evaluation resumes past them instead of running them again.
mkdir -p results/active_round2_hard
[ -f results/active_round2_hard/runs.jsonl ] || grep -E '"policy": "(gcs-open-loop|experiments/active_data/round1/active_step2000)"' \
    results/active_round1_hard/runs.jsonl > results/active_round2_hard/runs.jsonl
.venv/bin/gcs-push evaluate \
    --policies=[gcs-open-loop,experiments/active_data/round1/active_step2000,experiments/active_data/round2/active_step1000] \
    --sampler=hard --seed=3000 --num_initial_conditions=20 --runs=5 --timeout_s=60 --workers=2 --videos=1 \
    --output_dir=results/active_round2_hard
# Then, by the rule above, the protocol set (seed 1000), the same way from results/active_round1_seed1000.
