#!/usr/bin/env bash
# Active data, round 1 (session 10): run 7 (policies/diffusion_cpu until then) -> round 1, against an equal-cost control.
# Every step resumes after a kill (evaluate and generate/collect keep their finished work; re-run the line).
# Settings fixed before any evaluation of the fine-tuned weights:
#   - both arms fine-tune run 7 for 2000 steps of batch 32, bf16, peak lr 1e-4 (run 7's), seed 8000, on
#     the first 1000 of run 7's 3000 demonstrations plus their added data; step 2000 is the one evaluated
#     (planned 3000; cut to 2000 at step 40 of the first arm, before any evaluation, to fit the session);
#   - the arms differ only in the added data: active = expert labels of the policy's own states;
#     control = fresh GCS demonstrations from the hard sampler (the best non-interactive sampler for the
#     failures seen), as many frames as the active data (`--frames`);
#   - compared on the hard set (seed 3000, 20 x 5, 60 s timeout, no disturbances), then the winner under
#     the full protocol: seeds 1000, 2000 and the hard set, with and without disturbances.
set -euo pipefail
export HF_HUB_OFFLINE=1
R=outputs/active/round1

# Run 7: policies/diffusion_cpu as of commit 3bc727d (round 1 has replaced it since), under a name of its own.
mkdir -p outputs/policies
[ -d outputs/policies/run7 ] || { git archive 3bc727d policies/diffusion_cpu | tar -x -C outputs/policies \
    && mv outputs/policies/policies/diffusion_cpu outputs/policies/run7 && rmdir outputs/policies/policies; }

# The base data: the first 1000 of run 7's demonstrations (same seed, same Sobol stream).
.venv/bin/gcs-push generate --episodes=1000 --repo_id=local/gcs_push_box_1000 --workers=2

# 1. Roll run 7 out on hard initial conditions (a seed apart from every evaluation set), with and without
#    disturbances. (Planned: 40 more on the Sobol stream, seed 4001; dropped for the session's time.)
.venv/bin/gcs-push evaluate --policies=[outputs/policies/run7] --disturbances=true --sampler=hard --seed=4000 \
    --num_initial_conditions=60 --runs=1 --timeout_s=60 --workers=2 --videos=0 --output_dir=$R/rollouts_hard

# 2. Branch states labelled by the closed-loop expert.
.venv/bin/gcs-push collect --rollouts=[$R/rollouts_hard] --repo_id=local/gcs_push_r1_active --workers=2 --resume=true

# The control: as many frames of fresh hard-sampler GCS demonstrations (FRAMES = the active data's).
FRAMES=$(.venv/bin/python -c "import json,os;print(json.load(open(os.path.expanduser('~/.cache/huggingface/lerobot/local/gcs_push_r1_active/meta/info.json')))['total_frames'])")
.venv/bin/gcs-push generate --episodes=2000 --frames="$FRAMES" --sampler=hard --seed=4002 \
    --repo_id=local/gcs_push_r1_control --workers=2 --resume=true

# 3. Merges, with LeRobot's aggregation (delete a half-written output folder before re-running one).
for arm in active control; do
    .venv/bin/lerobot-edit-dataset --new_repo_id local/gcs_push_r1_${arm}_merged --operation.type merge \
        --operation.repo_ids "['local/gcs_push_box_1000', 'local/gcs_push_r1_${arm}']"
done

# 4. Fine-tune both arms from run 7 (resume a killed run with --resume=true --config_path=<its train_config.json>).
#    The active arm ran in session 10, the control arm in session 11.
for arm in active control; do
    OMP_NUM_THREADS=2 .venv/bin/lerobot-train --config_path=configs/policy/diffusion_cpu.json \
        --policy.path=outputs/policies/run7 --dataset.repo_id=local/gcs_push_r1_${arm}_merged \
        --output_dir=outputs/train/r1_${arm} --job_name=r1_${arm} --steps=2000 --save_freq=1000 \
        --policy.use_amp=true --policy.optimizer_lr=1e-4 --seed=8000 --num_workers=1
    .venv/bin/python -c "from lerobot_gcs_push.checkpoints import export_policy; export_policy('outputs/train/r1_${arm}/checkpoints/002000/pretrained_model', 'experiments/active_data/round1/${arm}_step2000')"
done

# 5. Evaluate: the hard set, run 7 beside both arms.
.venv/bin/gcs-push evaluate \
    --policies=[gcs-open-loop,outputs/policies/run7,experiments/active_data/round1/active_step2000,experiments/active_data/round1/control_step2000] \
    --sampler=hard --seed=3000 --num_initial_conditions=20 --runs=5 --timeout_s=60 --workers=2 --videos=1 \
    --output_dir=results/active_round1_hard
