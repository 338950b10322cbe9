#!/usr/bin/env bash
# Active data, round 8 (written in session 15, to finish in session 16): round 7 (shipped) -> round 8, with
# the rollouts back on all hard families, since round 7's corner-aimed rollouts left the goal side thin
# (hard test IC 16 at 2 of 5; goal side 0.77 on the hard validation set against round 6's 0.87).
# Every step resumes after a kill (re-run the script; delete a half-written merge folder first).
# Settings fixed before any round-8 step ran (written 05:52, session 15):
#   - rollouts of round 7, 1 run each, with and without disturbances, on 80 hard initial conditions (seed
#     4060, 20 of each family) and 20 uniform ones (seed 4061): round 6's mix;
#   - collect with the command's defaults; the training data are the base demonstrations plus the branch
#     states of rounds 1, 2, 4, 5, 6, 7 and 8 (every round's, as DAgger does);
#   - fine-tune round 7 for 4000 steps of batch 32, bf16, peak lr 1e-4, seed 8007; step 4000 is the one
#     evaluated;
#   - candidates: round 7 (shipped) and round 8;
#   - rule: on a fifth validation set no one has looked at, 40 hard (seed 5010) and 40 uniform (seed 5011)
#     initial conditions x 3 runs, no disturbances, 60 s, the candidate with the higher success at 0.1 m
#     over the 240 runs ships; a tie keeps round 7. Step 6 applies the rule; a new policy is then run on
#     the test sets (seeds 1000, 2000, 3000, with and without disturbances) and ships whatever they give.
#     Every result is reported.
set -euo pipefail
export HF_HUB_OFFLINE=1
C=~/.cache/huggingface/lerobot/local
E=experiments/active_data
P=$E/round7/active_step4000
R8=$E/round8/active_step4000
mkdir -p $E/round8

commit() {  # commit PATH MESSAGE, waiting for another git process to let go of the index
    while [ -f .git/index.lock ]; do sleep 5; done
    git add "$1" && git commit -q -m "$2" -- "$1" || true
}

# 0. The data earlier rounds trained on, rebuilt from what git keeps.
[ -f $C/gcs_push_box_1000/meta/info.json ] || \
    .venv/bin/gcs-push generate --episodes=1000 --repo_id=local/gcs_push_box_1000 --workers=2 --resume=true
# Every earlier round's exact states, rebuilt from the list it kept (rounds 1-6 picked theirs before
# `collect` capped each run after its checks).
for r in 1 2 4 5 6 7; do
    [ -f $C/gcs_push_r${r}_active/meta/info.json ] && continue
    n=$(.venv/bin/python -c "import json; print(len(json.load(open('$E/round$r/branch_states.json'))))")
    .venv/bin/gcs-push generate --expert=closed-loop --initial_conditions=$E/round$r/branch_states.json \
        --episodes=$n --repo_id=local/gcs_push_r${r}_active --workers=2 --resume=true
done
[ "${STOP_AFTER_REBUILD:-0}" = 1 ] && exit 0

# 1. Rollouts of round 7, with regret.
.venv/bin/gcs-push evaluate --policies=[$P] --disturbances=true --sampler=hard --seed=4060 \
    --num_initial_conditions=80 --runs=1 --timeout_s=60 --workers=2 --videos=0 --output_dir=$E/round8/rollouts_hard
.venv/bin/gcs-push evaluate --policies=[$P] --disturbances=true --sampler=uniform --seed=4061 \
    --num_initial_conditions=20 --runs=1 --timeout_s=60 --workers=2 --videos=0 --output_dir=$E/round8/rollouts_uniform

# 2. Branch states labelled by the closed-loop expert.
.venv/bin/gcs-push collect --rollouts=[$E/round8/rollouts_hard,$E/round8/rollouts_uniform] \
    --repo_id=local/gcs_push_r8_active --workers=2 --resume=true
cp $C/gcs_push_r8_active.branch_states.json $E/round8/branch_states.json
[ "${STOP_AFTER_COLLECT:-0}" = 1 ] && exit 0

# 3. Merge with LeRobot's aggregation.
if [ ! -f $C/gcs_push_r8_merged/meta/info.json ]; then
    rm -rf $C/gcs_push_r8_merged
    .venv/bin/lerobot-edit-dataset --new_repo_id local/gcs_push_r8_merged --operation.type merge \
        --operation.repo_ids "['local/gcs_push_box_1000', 'local/gcs_push_r1_active', 'local/gcs_push_r2_active', 'local/gcs_push_r4_active', 'local/gcs_push_r5_active', 'local/gcs_push_r6_active', 'local/gcs_push_r7_active', 'local/gcs_push_r8_active']"
fi

# 4. Fine-tune round 7 (resume a killed run with --resume=true --config_path=<its train_config.json>).
if [ ! -f $R8/model.safetensors ]; then
    OMP_NUM_THREADS=2 .venv/bin/lerobot-train --config_path=configs/policy/diffusion_cpu.json \
        --policy.path=$P --dataset.repo_id=local/gcs_push_r8_merged \
        --output_dir=outputs/train/r8_active --job_name=r8_active --steps=4000 --save_freq=1000 \
        --policy.use_amp=true --policy.optimizer_lr=1e-4 --seed=8007 --num_workers=1
    .venv/bin/python -c "from lerobot_gcs_push.checkpoints import export_policy; export_policy('outputs/train/r8_active/checkpoints/004000/pretrained_model', '$R8')"
    commit $E/round8 "Round 8 active arm: step 4000 weights (fp16), fine-tuned from round 7; not yet evaluated"
fi

# 5. The fifth validation set.
for v in "hard 5010" "uniform 5011"; do
    set -- $v
    .venv/bin/gcs-push evaluate --policies=[gcs-open-loop,$P,$R8] \
        --sampler=$1 --seed=$2 --num_initial_conditions=40 --runs=3 --timeout_s=60 --workers=2 --videos=0 \
        --output_dir=results/selection_$1_seed$2
done
.venv/bin/python experiments/scripts/hard_families.py results/selection_hard_seed5010
[ "${STOP_AFTER_VALIDATION:-0}" = 1 ] && exit 0

# 6. The rule, then the test sets for a new policy, beside GCS and round 7, whose rows are copied from
#    results/active_round7_* (a record does not depend on when it ran).
winner=$(.venv/bin/python - "$P" "$R8" <<'PY'
import json, sys
old, new = sys.argv[1:]
wins = {old: 0, new: 0}
for d in ("results/selection_hard_seed5010", "results/selection_uniform_seed5011"):
    for line in open(f"{d}/runs.jsonl"):
        rec = json.loads(line)
        if rec["policy"] in wins and not rec["disturbances"]:
            wins[rec["policy"]] += bool(rec["success"])
print(f"validation successes: {wins}", file=sys.stderr)
print(new if wins[new] > wins[old] else old)
PY
)
echo "by the rule: $winner"
[ "$winner" = "$R8" ] || exit 0
KEEP='"policy": "(gcs-open-loop|gcs-closed-loop|experiments/active_data/round7/active_step4000)"'
for s in seed1000 seed2000 hard; do
    mkdir -p results/active_round8_$s
    [ -f results/active_round8_$s/runs.jsonl ] || grep -E "$KEEP" results/active_round7_$s/runs.jsonl > results/active_round8_$s/runs.jsonl
done
.venv/bin/gcs-push evaluate --policies=[gcs-open-loop,$P,$R8] --disturbances=true \
    --seed=1000 --num_initial_conditions=20 --runs=5 --timeout_s=60 --workers=2 --videos=1 \
    --output_dir=results/active_round8_seed1000
.venv/bin/gcs-push evaluate --policies=[gcs-open-loop,gcs-closed-loop,$P,$R8] \
    --disturbances=true --seed=2000 --num_initial_conditions=20 --runs=5 --timeout_s=60 --workers=2 --videos=1 \
    --output_dir=results/active_round8_seed2000
.venv/bin/gcs-push evaluate --policies=[gcs-open-loop,gcs-closed-loop,$P,$R8] \
    --disturbances=true --sampler=hard --seed=3000 --num_initial_conditions=20 --runs=5 --timeout_s=60 \
    --workers=2 --videos=1 --output_dir=results/active_round8_hard
.venv/bin/python experiments/scripts/hard_families.py results/active_round8_hard
