#!/usr/bin/env bash
# Round 10c: does a longer schedule shorten the path further? Settings and rule fixed before any of its steps
# ran and before round 10b's test sets were done (session 19, 15:55):
#   - round 10b (round 9 + 2500 steps on round 10's data) was 5.6% faster than round 10 (+1500 steps) on the
#     ninth validation set, and round 9 (4000 steps) was the fastest on the test sets. 10c continues 10b on
#     the same merged data (local/gcs_push_r10_merged, still in this machine's cache) for 2000 more steps at
#     half the peak lr (5e-5), so its warm-up undoes less of 10b; bf16, seed 8012; step 2000 is the one
#     evaluated;
#   - rule, as round 10b's: on a tenth validation set no one has looked at, 40 hard (seed 5022) and 40
#     uniform (seed 5023) initial conditions x 3 runs, no disturbances, 60 s, round 10c replaces round 10b
#     only with at least 3 more successes over the 240 runs, or, within 2 either way, a mean simulation time
#     of the successful runs at least 5% lower (validation_winner.py --margin=3 --time_gain=0.05). Then the
#     test sets (seeds 1000, 2000, 3000) run beside round 10b, whose rows are copied from
#     results/active_round10b_*, and it ships whatever they give.
set -euo pipefail
export HF_HUB_OFFLINE=1
E=experiments/active_data
B=$E/round10b/active_step2500
R10C=$E/round10c/active_step2000
mkdir -p $E/round10c

commit() {  # commit PATH MESSAGE, waiting for another git process to let go of the index
    while [ -f .git/index.lock ]; do sleep 5; done
    git add "$1" && git commit -q -m "$2" -- "$1" || true
}

# 1. Continue round 10b on round 10's merged data (round10.sh steps 0-3 make it on a fresh machine).
if [ ! -f $R10C/model.safetensors ]; then
    OMP_NUM_THREADS=2 .venv/bin/lerobot-train --config_path=configs/policy/diffusion_cpu.json \
        --policy.path=$B --dataset.repo_id=local/gcs_push_r10_merged \
        --output_dir=outputs/train/r10c_active --job_name=r10c_active --steps=2000 --save_freq=500 \
        --policy.use_amp=true --policy.optimizer_lr=5e-5 --seed=8012 --num_workers=1
    .venv/bin/python -c "from lerobot_gcs_push.checkpoints import export_policy; export_policy('outputs/train/r10c_active/checkpoints/002000/pretrained_model', '$R10C')"
    commit $E/round10c "Round 10c: step 2000 weights (fp16), round 10b continued on round 10's data; not yet evaluated"
fi

# 2. The tenth validation set.
for v in "hard 5022" "uniform 5023"; do
    set -- $v
    .venv/bin/gcs-push evaluate --policies=[gcs-open-loop,$B,$R10C] \
        --sampler=$1 --seed=$2 --num_initial_conditions=40 --runs=3 --timeout_s=60 --workers=2 --videos=0 \
        --output_dir=results/selection_$1_seed$2
done
.venv/bin/python experiments/scripts/hard_families.py results/selection_hard_seed5022
[ "${STOP_AFTER_VALIDATION:-0}" = 1 ] && exit 0

# 3. The rule, then the test sets.
winner=$(.venv/bin/python experiments/scripts/validation_winner.py --margin=3 --time_gain=0.05 $B $R10C \
    results/selection_hard_seed5022 results/selection_uniform_seed5023)
echo "by the rule: $winner"
[ "$winner" = "$R10C" ] || exit 0
KEEP="\"policy\": \"(gcs-open-loop|gcs-closed-loop|$B)\""
for s in seed1000 seed2000 hard; do
    mkdir -p results/active_round10c_$s
    [ -f results/active_round10c_$s/runs.jsonl ] || grep -E "$KEEP" results/active_round10b_$s/runs.jsonl > results/active_round10c_$s/runs.jsonl
done
.venv/bin/gcs-push evaluate --policies=[gcs-open-loop,$B,$R10C] --disturbances=true \
    --seed=1000 --num_initial_conditions=20 --runs=5 --timeout_s=60 --workers=2 --videos=1 \
    --output_dir=results/active_round10c_seed1000
.venv/bin/gcs-push evaluate --policies=[gcs-open-loop,gcs-closed-loop,$B,$R10C] \
    --disturbances=true --seed=2000 --num_initial_conditions=20 --runs=5 --timeout_s=60 --workers=2 --videos=1 \
    --output_dir=results/active_round10c_seed2000
.venv/bin/gcs-push evaluate --policies=[gcs-open-loop,gcs-closed-loop,$B,$R10C] \
    --disturbances=true --sampler=hard --seed=3000 --num_initial_conditions=20 --runs=5 --timeout_s=60 \
    --workers=2 --videos=1 --output_dir=results/active_round10c_hard
.venv/bin/python experiments/scripts/hard_families.py results/active_round10c_hard
