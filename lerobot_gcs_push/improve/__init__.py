"""`gcs-push improve`: rounds of active data, from a policy folder or from nothing, until the policy is robust.
For the box, and for sliders that turn (gym-pusht's PushT: `--config_path=configs/improve/pusht.json`),
whose branch states are where coverage stalls rather than chunks of large regret (`stalls.py`).

A round: roll the current policy out beside GCS (hard and uniform initial conditions, with and without
disturbances, on seeds no evaluation set uses) -> stop here if it meets the targets on these fresh
conditions -> `collect` branch states labelled by the expert -> merge them with the base demonstrations
and every earlier round's states (LeRobot's aggregation) -> fine-tune the current weights -> a fresh
validation set, decided by the shipping rule (`shipping.py`) -> ship into the policy folder, or keep the
old one. From nothing, base demonstrations and a first training come before round 1; from a committed
base (`from_policy`), its weights are copied in and the demonstrations it learned from replayed from their
lists (`base.lists`). It also stops on a budget of rounds or hours.

Every stage resumes after `kill -9`. What another machine needs to resume is small: the policy folder and
`state_dir` (the state file: stages done, their wall times, each round's scores and decision, drawn as
`curve.png` after every round's rollouts; each round's branch-state list; the candidate awaiting its
decision; the newest checkpoint of an unfinished training in fp16). Commit both and re-run the same
command: datasets are rebuilt from the lists (the same expert, states and seeds give the same episodes)
and rollouts or validation runs a later stage needs are made again (seeded, so the same).

Each default is a lesson of the eleven hand-run rounds (experiments/active_data/README.md), named beside it.

One round of expert takeover for a keypoint policy, by hand (issue 65; BASE is its pretrained_model folder,
e.g. the learnability benchmark's position policy, trained by configs/train/pusht_keypoints.json). The obs
type comes from the policy's config: evaluate makes gym-pusht with `environment_state_agent_pos` for it and
records that in runs.jsonl, and collect has the expert recorded the same way (with its replay list):

    # 1. the policy on gym-pusht's own resets, on a seed no evaluation set uses (about 8 s a 30 s run on a core)
    gcs-push evaluate --env_id=gym_pusht/PushT-v0 --policies='[BASE]' --num_initial_conditions=100 \
        --runs=1 --seed=7100 --videos=0 --output_dir=outputs/takeover/r1/rollouts
    # 2. the closed-loop GCS expert from the states where its coverage stalls (`stalls.py`), failed and slow
    #    runs only (about 30 s an episode on a core, planning included)
    gcs-push collect --rollouts='[outputs/takeover/r1/rollouts]' --max_per_run=4 --seed=1 --workers=1 \
        --repo_id=local/takeover_r1 --root=outputs/takeover/r1/data
    # 3. fine-tune BASE on its pool and the takeover list: its weights, EMA and normalisation are BASE's
    #    (`--data.episodes=null`: every episode of the lists; the config's 1000 would be the pool alone)
    POOL=experiments/pusht/demos/position/seed480 TAKEOVER=outputs/takeover/r1/data/meta/gcs_push_replay.json
    gcs-push train --config_path=configs/train/pusht_keypoints.json --init_from=BASE --data.episodes=null \
        --data.lists="[${POOL}0.json,${POOL}1.json,${POOL}2.json,${POOL}3.json,${TAKEOVER}]" \
        --schedule.steps=5000 --output_dir=outputs/takeover/r1/train
    # 4. judged as the base was, by LeRobot's own evaluation
    lerobot-eval --policy.path=outputs/takeover/r1/train/pretrained_model --env.type=pusht \
        --env.obs_type=environment_state_agent_pos --eval.n_episodes=100 --eval.batch_size=10 \
        --eval.use_async_envs=false --policy.device=cpu

The next round rolls out r1's policy, and trains with `--init_from=` it on the pool and both takeover lists.
The fine-tune's length and learning rate are open (5000 steps is a guess, not a measurement); its EMA's
power schedule restarts at step 0, so the saved weights follow the fine-tune closely from its first steps.
train_config.json's `outside_stats_range` tells how much of the new data lies beyond the base's extremes.
"""

import contextlib

from lerobot_gcs_push.improve.config import (
    STAGES,
    BaseConfig,
    ImproveConfig,
    RoundConfig,
    StopConfig,
    ValidationConfig,
)
from lerobot_gcs_push.improve.improver import Improver
from lerobot_gcs_push.improve.state import STATE_FILE, State, StopRequested

__all__ = [
    "STAGES",
    "STATE_FILE",
    "BaseConfig",
    "ImproveConfig",
    "Improver",
    "RoundConfig",
    "State",
    "StopConfig",
    "StopRequested",
    "ValidationConfig",
    "improve",
]


def improve(cfg: ImproveConfig) -> dict:
    with contextlib.suppress(StopRequested):
        return Improver(cfg).run()
    print(f"stopped after {cfg.stop_after}, as asked; run the same command again to continue")
    return {"stopped": f"after {cfg.stop_after}", "rounds": []}
