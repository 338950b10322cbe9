"""gym-pusht's demonstrations in `lerobot/pusht`'s format, so that LeRobot's `--env.type=pusht` trains on them.

`lerobot/pusht` (and LeRobot's `pusht` env config, `obs_type="pixels_agent_pos"`, whose `features_map` sends
`pixels` to `observation.image` and `agent_pos` to `observation.state`) has exactly these features:
`observation.image` (the env's own 96 x 96 render, stored as video), `observation.state` (the agent's
position, px), `action` (the agent's target, px), `next.reward`, `next.done` and `next.success`, at 10 fps.
No `observation.environment_state`: the env LeRobot evaluates in never gives one, so a policy trained to
expect it could not run there.

`next.*` of a frame are what the env's step from that frame's observation returned: its reward, its
success, and done (the episode's last frame, which a kept episode reaches by succeeding).
"""

from __future__ import annotations

import numpy as np

from lerobot_gcs_push.pusht_frame import ARENA_PX

PUSHT_FEATURE_KEYS = (
    "observation.image",
    "observation.state",
    "action",
    "next.reward",
    "next.done",
    "next.success",
)


def pusht_features(image_size: int = 96) -> dict:
    """lerobot/pusht's features (names as there), the image `image_size` px square."""
    motors = {"motors": ["motor_0", "motor_1"]}
    return {
        "observation.image": {
            "dtype": "video",
            "shape": (image_size, image_size, 3),
            "names": ["height", "width", "channel"],
        },
        "observation.state": {"dtype": "float32", "shape": (2,), "names": motors},
        "action": {"dtype": "float32", "shape": (2,), "names": motors},
        "next.reward": {"dtype": "float32", "shape": (1,), "names": None},
        "next.done": {"dtype": "bool", "shape": (1,), "names": None},
        "next.success": {"dtype": "bool", "shape": (1,), "names": None},
    }


class PushTFrames:
    """Records a gym-pusht rollout as lerobot/pusht's frames: pass `frames.env` to `rollout` in place of the
    env. Each step stores the observation the action was chosen from, the action as the env ran it (clipped
    to the arena and rounded to float32, so that replaying the stored actions repeats the episode exactly)
    and what that step returned."""

    def __init__(self, env):
        self.env = _Recording(env, self)
        self.frames: dict[str, list] = {k: [] for k in PUSHT_FEATURE_KEYS}

    def __len__(self) -> int:
        return len(self.frames["action"])

    def arrays(self) -> dict[str, np.ndarray]:
        return {k: np.stack(v) for k, v in self.frames.items()}

    def _record(self, obs, action, reward, done, success) -> None:
        f = self.frames
        f["observation.image"].append(np.asarray(obs["pixels"], np.uint8))
        f["observation.state"].append(np.asarray(obs["agent_pos"], np.float32))
        f["action"].append(action)
        f["next.reward"].append(np.array([reward], np.float32))
        f["next.done"].append(np.array([done], bool))
        f["next.success"].append(np.array([success], bool))


class _Recording:
    """The env, with each step recorded into `PushTFrames`; everything else is the env's."""

    def __init__(self, env, frames: PushTFrames):
        self._env, self._frames, self._obs = env, frames, None

    def __getattr__(self, name):
        return getattr(self._env, name)

    def reset(self, **kwargs):
        obs, info = self._env.reset(**kwargs)
        self._obs = obs
        return obs, info

    def step(self, action):
        target = np.asarray(action, np.float64)
        if target.shape == (2,) and np.all(np.isfinite(target)):  # else the env's own error
            target = np.clip(target, 0.0, ARENA_PX).astype(np.float32)
        obs, reward, terminated, truncated, info = self._env.step(target)
        done = bool(terminated or truncated)
        self._frames._record(self._obs, target, float(reward), done, bool(info["is_success"]))
        self._obs = obs
        return obs, reward, terminated, truncated, info
