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
