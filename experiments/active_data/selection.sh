#!/usr/bin/env bash
# Session 13: choose the shipped policy on initial conditions no one has looked at, instead of on the hard
# set (seed 3000) that has already chosen between rounds three times.
# Settings and rule fixed before any step ran (written 22:50, session 13):
#   - candidates: round 3 (policies/diffusion_cpu, shipped), round 4 (not shipped: 0.92 on the hard set),
#     and the mean of their weights (experiments/scripts/average_weights.py; round 3's processors, whose
#     statistics agree with round 4's within 1e-3);
#   - validation set: the hard sampler, seed 5000 (never used: rollouts used 4000-4021, evaluations 1000,
#     2000, 3000), 40 initial conditions x 3 runs, no disturbances, 60 s, beside GCS open loop;
#   - rule: the candidate with the highest success at 0.1 m on the validation set becomes
#     policies/diffusion_cpu; a tie with round 3 keeps round 3. A new policy is then run on every test
#     set (seeds 1000, 2000 and 3000, 20 x 5, with and without disturbances) and ships whatever those
#     give: the test sets report, they do not choose. Every result is reported.
# Every step resumes after a kill (gcs-push evaluate continues in its output folder).
set -euo pipefail
export HF_HUB_OFFLINE=1
E=experiments/active_data

[ -f $E/soup_r3_r4/model.safetensors ] || .venv/bin/python experiments/scripts/average_weights.py \
    $E/round3/active_step2000 $E/round4/active_step2000 --output $E/soup_r3_r4

.venv/bin/gcs-push evaluate \
    --policies=[gcs-open-loop,$E/round3/active_step2000,$E/round4/active_step2000,$E/soup_r3_r4] \
    --sampler=hard --seed=5000 --num_initial_conditions=40 --runs=3 --timeout_s=60 --workers=2 --videos=0 \
    --output_dir=results/selection_hard_seed5000
.venv/bin/python experiments/scripts/hard_families.py results/selection_hard_seed5000
[ "${STOP_AFTER_SELECTION:-0}" = 1 ] && exit 0

# 2. (By the rule: the weight average won the validation set, 0.96 against 0.94 and 0.95.) The test sets,
#    with and without disturbances, beside GCS and round 3, whose rows are copied from round 3's folders
#    (a record does not depend on when it ran); this runs the average's 200 runs per set.
S=$E/soup_r3_r4
R3='"policy": "(gcs-open-loop|gcs-closed-loop|experiments/active_data/round3/active_step2000)"'
copy_rows() {  # copy_rows DEST SRC...: the GCS and round-3 records of earlier evaluations
    local dest=$1; shift
    mkdir -p "$dest"
    [ -f "$dest/runs.jsonl" ] || cat "$@" | grep -E "$R3" | sort -u > "$dest/runs.jsonl"
}
copy_rows results/active_soup_seed1000 results/active_round3_seed1000/runs.jsonl
copy_rows results/active_soup_seed2000 results/active_round3_seed2000/runs.jsonl
copy_rows results/active_soup_hard results/active_round3_hard/runs.jsonl results/active_round3_hard_dist/runs.jsonl
.venv/bin/gcs-push evaluate --policies=[gcs-open-loop,$E/round3/active_step2000,$S] --disturbances=true \
    --seed=1000 --num_initial_conditions=20 --runs=5 --timeout_s=60 --workers=2 --videos=1 \
    --output_dir=results/active_soup_seed1000
.venv/bin/gcs-push evaluate --policies=[gcs-open-loop,gcs-closed-loop,$E/round3/active_step2000,$S] \
    --disturbances=true --seed=2000 --num_initial_conditions=20 --runs=5 --timeout_s=60 --workers=2 --videos=1 \
    --output_dir=results/active_soup_seed2000
.venv/bin/gcs-push evaluate --policies=[gcs-open-loop,gcs-closed-loop,$E/round3/active_step2000,$S] \
    --disturbances=true --sampler=hard --seed=3000 --num_initial_conditions=20 --runs=5 --timeout_s=60 \
    --workers=2 --videos=1 --output_dir=results/active_soup_hard
.venv/bin/python experiments/scripts/hard_families.py results/active_soup_hard
