"""`GcsPushEnv`'s action and observation spaces, from its `Scene` and `obs_type` (see the env's
docstring for what each holds)."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from gymnasium import spaces

if TYPE_CHECKING:
    from lerobot_gcs_push.scene import Scene


def action_space(scene: Scene) -> spaces.Box:
    lim = scene.finger_limit
    return spaces.Box(-lim, lim, shape=(2,), dtype=np.float64)


def observation_space(scene: Scene, obs_type: str) -> spaces.Space:
    """The space of `obs_type`'s observations; the image has the scene camera's size."""
    # The finger may overshoot a command at the limit by the PID's few millimetres, and the box may be
    # pushed or knocked past its workspace: the view edge bounds the finger, nothing bounds the box.
    agent = spaces.Box(-scene.view_half_width, scene.view_half_width, shape=(2,), dtype=np.float64)
    if obs_type == "state":
        high = np.array([scene.view_half_width] * 2 + [np.inf] * 2 + [math.pi] * (scene.kind.pose_size - 2))
        return spaces.Box(-high, high, dtype=np.float64)
    if obs_type == "environment_state_agent_pos":
        high = np.array([np.inf, np.inf, math.pi])
        return spaces.Dict({"environment_state": spaces.Box(-high, high, dtype=np.float64), "agent_pos": agent})
    rows, cols = scene.camera.height, scene.camera.width
    return spaces.Dict(
        {
            "pixels": spaces.Box(0, 255, shape=(rows, cols, 3), dtype=np.uint8),
            "agent_pos": agent,
        }
    )
