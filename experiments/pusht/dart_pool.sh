#!/usr/bin/env bash
# The DART pool (issue 65): the position pool's starts (gym-pusht's resets of seeds 4800-4803, 250 successes
# each) by the default expert with DART's command noise of 4 px (`--command_noise_px=4`): the env runs each
# target plus a seeded draw, the dataset records the target. Keypoint datasets (no rendering: the list
# rebuilds either kind). Each list lands in demos/dart4/ as its stage ends (commit it). Resumable.
#   bash experiments/pusht/dart_pool.sh [SEEDS...]     WORKERS=1 to leave a core free
set -eu
cd "$(dirname "$0")/../.."
home=${HF_LEROBOT_HOME:-$HOME/.cache/huggingface/lerobot}
mkdir -p experiments/pusht/demos/dart4
for s in ${@:-4800 4801 4802 4803}; do
  out=experiments/pusht/demos/dart4/seed$s.json
  [ -f "$out" ] && { echo "$out is there"; continue; }
  .venv/bin/gcs-push generate --env_id=gym_pusht/PushT-v0 --episodes=250 --seed="$s" --command_noise_px=4 \
    --obs_type=environment_state_agent_pos --repo_id="local/gcs_pusht_dart4_s$s" --workers="${WORKERS:-2}" \
    --resume=true --progress=false
  cp "$home/local/gcs_pusht_dart4_s$s/meta/gcs_push_replay.json" "$out"
done
