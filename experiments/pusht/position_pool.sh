#!/usr/bin/env bash
# The position-command pool (issue 65): gym-pusht's resets of seeds 4800-4803 (the first pool's starts, in
# its order), 250 demonstrations each, by the expert's default commands; each list lands in demos/position/
# as its stage ends (commit it). Resumable: run it again after a kill.
#   LEAD=K bash experiments/pusht/position_pool.sh [SEEDS...]   commands leading K actions (`--expert.lead_actions`),
#                                                              keypoint datasets, lists into demos/leadK/
set -eu
cd "$(dirname "$0")/../.."
home=${HF_LEROBOT_HOME:-$HOME/.cache/huggingface/lerobot}
name=position extra=()
if [ -n "${LEAD:-}" ]; then
  name=lead$LEAD extra=(--expert.lead_actions="$LEAD" --obs_type=environment_state_agent_pos)
fi
mkdir -p "experiments/pusht/demos/$name"
for seed in "${@:-4800 4801 4802 4803}"; do
  for s in $seed; do
    out=experiments/pusht/demos/$name/seed$s.json
    [ -f "$out" ] && { echo "$out is there"; continue; }
    .venv/bin/gcs-push generate --env_id=gym_pusht/PushT-v0 --episodes=250 --seed="$s" \
      --repo_id="local/gcs_pusht_${name}_s$s" --workers="${WORKERS:-2}" --resume=true --progress=false "${extra[@]}"
    cp "$home/local/gcs_pusht_${name}_s$s/meta/gcs_push_replay.json" "$out"
  done
done
