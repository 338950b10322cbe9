#!/usr/bin/env bash
# The position-command pools (issue 65): gym-pusht's resets of seeds 4800-4803 (the first pool's starts, in
# its order), 250 demonstrations each; each list lands in demos/<pool>/ as its stage ends (commit it).
# Resumable: run it again after a kill.
#   bash experiments/pusht/position_pool.sh [SEEDS...]   the expert's default commands: demos/position/
#   LEAD=K    commands leading K actions (`--expert.lead_actions`): demos/leadK/
#   NOISE=S   DART: the env runs each command plus S px of noise, the list keeps the clean labels
#             (`--command_noise_px`): demos/<pool>_dartS/
#   FINISH=C  the demonstration goes on past gym-pusht's success until coverage C, or FINISH_FRAMES (60) steps
#             after it (`--finish_coverage`, `--finish_frames`): demos/<pool>_finishCC/
#   ARRIVE=V  the last 0.1 m of each plan's last push at V m/s at most (`--expert.arrive`): demos/<pool>_arriveVV/
#   LEAD, NOISE, FINISH and ARRIVE write keypoint datasets (no rendering: a list rebuilds either kind). WORKERS=1 leaves a core;
#   EPISODES=N demonstrations a seed (250).
set -eu
cd "$(dirname "$0")/../.."
home=${HF_LEROBOT_HOME:-$HOME/.cache/huggingface/lerobot}
name=position extra=()
if [ -n "${LEAD:-}" ]; then name=lead$LEAD extra+=(--expert.lead_actions="$LEAD"); fi
if [ -n "${NOISE:-}" ]; then name=${name}_dart$NOISE extra+=(--command_noise_px="$NOISE"); fi
if [ -n "${FINISH:-}" ]; then
  name=${name}_finish${FINISH#0.} extra+=(--finish_coverage="$FINISH" --finish_frames="${FINISH_FRAMES:-60}")
fi
if [ -n "${ARRIVE:-}" ]; then name=${name}_arrive${ARRIVE#0.} extra+=(--expert.arrive="$ARRIVE"); fi
if [ ${#extra[@]} -gt 0 ]; then extra+=(--obs_type=environment_state_agent_pos); fi
mkdir -p "experiments/pusht/demos/$name"
for seed in "${@:-4800 4801 4802 4803}"; do
  for s in $seed; do
    out=experiments/pusht/demos/$name/seed$s.json
    [ -f "$out" ] && { echo "$out is there"; continue; }
    .venv/bin/gcs-push generate --env_id=gym_pusht/PushT-v0 --episodes="${EPISODES:-250}" --seed="$s" \
      --repo_id="local/gcs_pusht_${name}_s$s" --workers="${WORKERS:-2}" --resume=true --progress=false "${extra[@]}"
    cp "$home/local/gcs_pusht_${name}_s$s/meta/gcs_push_replay.json" "$out"
  done
done
