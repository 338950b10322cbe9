#!/usr/bin/env bash
# One point of a learning curve: a checkpoint on 8 initial conditions x 1 run, 60 s of simulated time
# (GCS needs 22 s on average), one thread so that it can run beside the training.
#   results/train/eval_checkpoint.sh results/train/run2_nocrop outputs/train/gcs_push_diffusion_cpu_v2 002000
set -euo pipefail
run_dir=$1 train_dir=$2 step=$3
OMP_NUM_THREADS=1 MKL_NUM_THREADS=1 HF_HUB_OFFLINE=1 .venv/bin/gcs-push evaluate \
    --policy "$train_dir/checkpoints/$step/pretrained_model" --num-initial-conditions 8 --runs 1 \
    --timeout-s 60 --workers 1 --videos 0 --output-dir "$run_dir/learning_curve/step_$step"
