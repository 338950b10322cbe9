"""One rollout for every consumer: a policy in a pushing env (any registered id) from an initial condition.

Demonstrations, evaluation and active-data collection all run this loop and differ only in what they
keep (`on_step`). A policy is anything with `reset(obs, info, seed)` and `act(obs, info) -> action`: the
GCS experts read the true state from `info`, a learned policy only the observation. A policy may add
its own fields to the summary with `episode_summary()`.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Protocol

import numpy as np


def check_env_id(env_id: str) -> str:
    """`env_id` if it is one of the registered pushing envs, else a ValueError that lists them."""
    from lerobot_gcs_push.registration import SCENES

    if env_id not in SCENES:
        raise ValueError(f"unknown env_id {env_id!r}: choose one of {', '.join(SCENES)}")
    return env_id


class Policy(Protocol):
    def reset(self, obs: dict, info: dict, seed: int | None) -> None: ...

    def act(self, obs: dict, info: dict) -> np.ndarray: ...


def rollout(
    env,
    policy: Policy,
    box=None,
    finger=None,
    seed: int | None = None,
    on_step: Callable[[dict, np.ndarray, dict], None] | None = None,
    heading: float | None = None,
    pusht_state=None,
) -> dict:
    """Run one episode of `policy` in `env` (a GcsPushEnv, possibly wrapped) and summarise it.

    Without `box`/`finger` the env samples the initial condition from `seed`; `pusht_state` (gym-pusht's
    state vector of the same start) takes their place in gym-pusht; `heading` is a rotating
    slider's (None: the env's default, 0). `on_step(obs, action, info)` sees each action with the
    observation it was chosen from. The summary adds what the scene's slider kind records (a rotating
    slider's final pose, coverage and heading error)."""
    options = None if box is None else {"box": list(box), "finger": list(finger)}
    if options is not None and heading is not None:
        options["heading"] = float(heading)
    if pusht_state is not None:  # gym-pusht's own state of the same start: its reset lands on it exactly
        options = {"pusht_state": list(pusht_state)}
    obs, info = env.reset(seed=seed, options=options)
    policy.reset(obs, info, seed)
    t0 = time.perf_counter()
    terminated = truncated = False
    while not (terminated or truncated):
        action = policy.act(obs, info)
        if on_step is not None:
            on_step(obs, action, info)
        obs, _, terminated, truncated, info = env.step(action)
    summary = {
        "success": bool(info["is_success"]),
        "final_distance": float(info["box_goal_distance"]),
        "sim_time_s": float(info["sim_time_s"]),
        "run_time_s": time.perf_counter() - t0,  # wall clock of the loop: inference or replanning included
        "box_final": np.asarray(info["box"]).tolist(),
        "finger_final": np.asarray(info["finger"]).tolist(),
        "disturbances": info.get("disturbances", []),
    }
    summary |= env.unwrapped.scene.kind.summary(info)  # what the slider's kind records beyond its position
    extra = getattr(policy, "episode_summary", None)
    return summary | (extra() if extra is not None else {})
