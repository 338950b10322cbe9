"""Gymnasium registration of `GcsPushBox-v0`, kept free of Drake so that importing the package (and
its pure-optimisation planner) stays light; the env module loads only when an env is made."""

from __future__ import annotations

import gymnasium as gym

ENV_ID = "GcsPushBox-v0"


def register_envs() -> None:
    """Register `GcsPushBox-v0`; calling again is harmless. Importing the package calls it: the one way
    the id is registered (a `gymnasium.envs` entry point did not register it on `import gymnasium` with the
    gymnasium that lerobot 0.6.1 installs).

    No `max_episode_steps` here: the env truncates itself at `max_sim_time_s`, which depends on its
    kwargs, so a registry TimeLimit could only disagree with it.
    """
    if ENV_ID not in gym.envs.registry:
        gym.register(id=ENV_ID, entry_point="lerobot_gcs_push.env:GcsPushBoxEnv")
