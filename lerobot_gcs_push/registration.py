"""Gymnasium registration of the pushing envs, kept free of Drake so that importing the package (and its
pure-optimisation planner) stays light; the env module loads only when an env is made.

One env class, three scenes: the ids differ only in the `Scene` they pass, so the goal pose and the
success rule always come from the scene. A fourth id is gym-pusht's own env (`pusht.env.GymPushTTarget`
wraps it); its scene is gym-pusht's T in metres. `make_env` is the one place an env is made from an id.
"""

from __future__ import annotations

import math

import gymnasium as gym

from lerobot_gcs_push.pusht.env import GYM_PUSHT_ID, GymPushTTarget, pusht_scene, reset_states
from lerobot_gcs_push.scene import HARD_SAMPLERS, InitialCondition, Scene, sample_initial_conditions

ENV_ID = "GcsPushBox-v0"  # the paper's box, which cannot turn
SE2_ENV_ID = "GcsPushBoxSE2-v0"  # the same box on a yaw joint: position and heading to reach
TEE_ENV_ID = "GcsPushT-v0"  # gym-pusht's T in Drake, turned to gym-pusht's goal heading (y up: -pi/4)
PUSHT_ENV_ID = GYM_PUSHT_ID  # gym-pusht's own env (registered by gym_pusht), driven as a target


SCENES = {
    ENV_ID: Scene(),
    SE2_ENV_ID: Scene(slider="box", rotates=True, goal_heading=0.0),
    # Until 2026-12-05 the goal heading was +pi/4, gym-pusht's number in a y-up frame: its mirror image.
    TEE_ENV_ID: Scene(slider="tee", rotates=True, goal_heading=-math.pi / 4),
    PUSHT_ENV_ID: pusht_scene(),
}


def make_env(env_id: str, **kwargs):
    """The env of a registered id, unwrapped (the rollouts read `.scene` and `.fps` off it)."""
    if not SCENES[env_id].kind.drake_env:
        return GymPushTTarget(**kwargs)
    return gym.make(env_id, **kwargs).unwrapped


def register_envs() -> None:
    """Register the ids of `SCENES`; calling again is harmless. Importing the package calls it: the one way
    the ids are registered (a `gymnasium.envs` entry point did not register them on `import gymnasium`
    with the gymnasium that lerobot 0.6.1 installs).

    No `max_episode_steps` here: the env truncates itself at `max_sim_time_s`, which depends on its
    kwargs, so a registry TimeLimit could only disagree with it. `GcsPushBox-v0` passes no scene: its
    default is the paper's, as before the rotating ids existed.
    """
    for env_id, scene in SCENES.items():
        if env_id not in gym.envs.registry and scene.kind.drake_env:
            kwargs = {} if env_id == ENV_ID else {"scene": scene}
            gym.register(id=env_id, entry_point="lerobot_gcs_push.sim.env:GcsPushEnv", kwargs=kwargs)


def sample_starts(scene: Scene, n: int, seed: int = 0, sampler: str = "sobol") -> list[InitialCondition]:
    """The first `n` starts of a seeded stream: gym-pusht's own resets for a scene with its pixel frame
    (but for the box's hard families, which it refuses), else `scene.sample_initial_conditions`."""
    if scene.kind.own_resets and sampler not in HARD_SAMPLERS:
        return reset_states(scene, n, seed)
    return sample_initial_conditions(scene, n, seed=seed, sampler=sampler)
