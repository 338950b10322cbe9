"""Gymnasium registration of the pushing envs, kept free of Drake so that importing the package (and its
pure-optimisation planner) stays light; the env module loads only when an env is made.

One env class, three scenes: the ids differ only in the `Scene` they pass, so the goal pose and the
success rule always come from the scene.
"""

from __future__ import annotations

import math

import gymnasium as gym

from lerobot_gcs_push.scene import Scene

ENV_ID = "GcsPushBox-v0"  # the paper's box, which cannot turn
SE2_ENV_ID = "GcsPushBoxSE2-v0"  # the same box on a yaw joint: position and heading to reach
TEE_ENV_ID = "GcsPushT-v0"  # gym-pusht's T, goal heading pi/4 as there

SCENES = {
    ENV_ID: Scene(),
    SE2_ENV_ID: Scene(slider="box", rotates=True, goal_heading=0.0),
    TEE_ENV_ID: Scene(slider="tee", rotates=True, goal_heading=math.pi / 4),
}


def register_envs() -> None:
    """Register the ids of `SCENES`; calling again is harmless. Importing the package calls it: the one way
    the ids are registered (a `gymnasium.envs` entry point did not register them on `import gymnasium`
    with the gymnasium that lerobot 0.6.1 installs).

    No `max_episode_steps` here: the env truncates itself at `max_sim_time_s`, which depends on its
    kwargs, so a registry TimeLimit could only disagree with it. `GcsPushBox-v0` passes no scene: its
    default is the paper's, as before the rotating ids existed.
    """
    for env_id, scene in SCENES.items():
        if env_id not in gym.envs.registry:
            kwargs = {} if env_id == ENV_ID else {"scene": scene}
            gym.register(id=env_id, entry_point="lerobot_gcs_push.env:GcsPushBoxEnv", kwargs=kwargs)
