"""Gymnasium registration of `GcsPushBox-v0`, kept free of Drake so that importing the package (and
its pure-optimisation planner) stays light; the env module loads only when an env is made."""

from __future__ import annotations

import gymnasium as gym

ENV_IDS = ("GcsPushBox-v0", "gym_gcs_push/GcsPushBox-v0")


def register_envs() -> None:
    """Register `GcsPushBox-v0` and LeRobot's id for it; calling again is harmless.

    No `max_episode_steps` here: the env truncates itself at `max_sim_time_s`, which depends on its
    kwargs, so a registry TimeLimit could only disagree with it.
    """
    for env_id in ENV_IDS:
        if env_id not in gym.envs.registry:
            gym.register(id=env_id, entry_point="lerobot_gcs_push.env:GcsPushBoxEnv")
