#!/usr/bin/env bash
# The position-command pool (issue 65): gym-pusht's resets of seeds 4800-4803 (the first pool's starts, in
# its order), 250 demonstrations each, by the expert's default commands; each list lands in demos/position/
# as its stage ends (commit it). Resumable: run it again after a kill.
set -eu
cd "$(dirname "$0")/../.."
home=${HF_LEROBOT_HOME:-$HOME/.cache/huggingface/lerobot}
for seed in "${@:-4800 4801 4802 4803}"; do
  for s in $seed; do
    out=experiments/pusht/demos/position/seed$s.json
    [ -f "$out" ] && { echo "$out is there"; continue; }
    .venv/bin/gcs-push generate --env_id=gym_pusht/PushT-v0 --episodes=250 --seed="$s" \
      --repo_id="local/gcs_pusht_position_s$s" --workers=2 --resume=true
    cp "$home/local/gcs_pusht_position_s$s/meta/gcs_push_replay.json" "$out"
  done
done
