"""gym-pusht's demonstrations in `lerobot/pusht`'s format, so that LeRobot's `--env.type=pusht` trains on them.

`lerobot/pusht` (and LeRobot's `pusht` env config, `obs_type="pixels_agent_pos"`, whose `features_map` sends
`pixels` to `observation.image` and `agent_pos` to `observation.state`) has exactly these features:
`observation.image` (the env's own 96 x 96 render, stored as video), `observation.state` (the agent's
position, px), `action` (the agent's target, px), `next.reward`, `next.done` and `next.success`, at 10 fps.
With `obs_type="environment_state_agent_pos"` (LeRobot's `--env.obs_type` of the same name) the T's 8
keypoints take the image's place as `observation.environment_state`, exactly as that env maps them: a keypoint
policy trained on it runs in `lerobot-eval --env.type=pusht --env.obs_type=environment_state_agent_pos`.

`next.*` of a frame are what the env's step from that frame's observation returned: its reward, its
success, and done (the episode's last frame, which a kept episode reaches by succeeding).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lerobot_gcs_push.pusht.frame import ARENA_PX

PUSHT_FEATURE_KEYS = (
    "observation.image",
    "observation.state",
    "action",
    "next.reward",
    "next.done",
    "next.success",
)
# What LeRobot's `pusht` env gives for each obs_type (its `features_map`): pixels to `observation.image`,
# the keypoints to `observation.environment_state`, the agent to `observation.state`.
OBS_TYPES = {"pixels_agent_pos": "observation.image", "environment_state_agent_pos": "observation.environment_state"}


def pusht_feature_keys(obs_type: str = "pixels_agent_pos") -> tuple[str, ...]:
    """lerobot/pusht's feature keys, with the keypoints in place of the image for `environment_state_agent_pos`."""
    check_obs_type(obs_type)
    return (OBS_TYPES[obs_type], *PUSHT_FEATURE_KEYS[1:])


def check_obs_type(obs_type: str) -> str:
    if obs_type not in OBS_TYPES:
        raise ValueError(f"gym-pusht's datasets take obs_type {' or '.join(OBS_TYPES)}, got {obs_type!r}")
    return obs_type


def pusht_features(image_size: int = 96, obs_type: str = "pixels_agent_pos") -> dict:
    """lerobot/pusht's features (names as there), the image `image_size` px square; for
    `environment_state_agent_pos`, the T's 8 keypoints (16 values, px) in its place, as LeRobot's env maps them."""
    motors = {"motors": ["motor_0", "motor_1"]}
    if check_obs_type(obs_type) == "pixels_agent_pos":
        observation = {
            "observation.image": {
                "dtype": "video",
                "shape": (image_size, image_size, 3),
                "names": ["height", "width", "channel"],
            }
        }
    else:
        observation = {"observation.environment_state": {"dtype": "float32", "shape": (16,), "names": None}}
    return observation | {
        "observation.state": {"dtype": "float32", "shape": (2,), "names": motors},
        "action": {"dtype": "float32", "shape": (2,), "names": motors},
        "next.reward": {"dtype": "float32", "shape": (1,), "names": None},
        "next.done": {"dtype": "bool", "shape": (1,), "names": None},
        "next.success": {"dtype": "bool", "shape": (1,), "names": None},
    }


@dataclass(frozen=True)
class CommandNoise:
    """DART's noise (Laskey et al. 2017): the env runs each command plus a Gaussian draw of `std_px` a
    coordinate, while the dataset records the command itself. The states then stray from the expert's path
    as a policy's would, and every label is the closed-loop expert's correction from where it is.

    The draws are legacy `RandomState(seed)`'s normals, a stream NumPy keeps fixed across versions: the
    first n rows are the same whether drawn for one step or for a whole episode, so the commands run are
    exactly `commands_run` of the labels, here and in any replay."""

    std_px: float
    seed: int

    def __post_init__(self) -> None:
        if not (np.isfinite(self.std_px) and self.std_px >= 0):
            raise ValueError(f"command noise must be a finite std >= 0 px, got {self.std_px}")
        if not 0 <= int(self.seed) < 2**32:
            raise ValueError(f"command noise seed must be in [0, 2**32), got {self.seed}")

    @classmethod
    def of(cls, spec: dict) -> CommandNoise:
        """From a replay entry's or an episode's "command_noise" record."""
        try:
            return cls(float(spec["std_px"]), int(spec["seed"]))
        except (KeyError, TypeError, ValueError):
            raise ValueError(f'"command_noise" must be {{"std_px": s, "seed": n}}, got {spec!r}') from None

    def spec(self) -> dict:
        return {"std_px": self.std_px, "seed": int(self.seed)}

    def draws(self, n: int) -> np.ndarray:
        return np.random.RandomState(int(self.seed)).normal(0.0, self.std_px, (n, 2))

    def commands_run(self, labels: np.ndarray) -> np.ndarray:
        """What the env ran for each recorded command: label plus draw, clipped to the arena, as float32."""
        labels = np.asarray(labels, np.float32).reshape(-1, 2)
        return _run_target(labels.astype(np.float64) + self.draws(len(labels)))


def _run_target(target: np.ndarray) -> np.ndarray:
    """A target as gym-pusht is given it here: clipped to the arena, rounded to float32 (what is stored)."""
    return np.clip(target, 0.0, ARENA_PX).astype(np.float32)


class PushTFrames:
    """Records a gym-pusht rollout as lerobot/pusht's frames: pass `frames.env` to `rollout` in place of the
    env. Each step stores the observation the action was chosen from, the action as the env ran it (clipped
    to the arena and rounded to float32, so that replaying the stored actions repeats the episode exactly)
    and what that step returned. `obs_type` must be the env's.

    With `noise` (DART), the env runs the action plus the noise's draw for that step and the action is what
    is stored; `expected_run` (a replayed list's "actions") is then checked step by step against what ran,
    so a list replays exactly or says where it does not."""

    def __init__(self, env, obs_type: str = "pixels_agent_pos", noise: CommandNoise | None = None, expected_run=None):
        self.env = _Recording(env, self, noise, expected_run)
        self.keys = pusht_feature_keys(obs_type)
        self.frames: dict[str, list] = {k: [] for k in self.keys}

    def __len__(self) -> int:
        return len(self.frames["action"])

    def arrays(self) -> dict[str, np.ndarray]:
        return {k: np.stack(v) for k, v in self.frames.items()}

    def _record(self, obs, action, reward, done, success) -> None:
        f = self.frames
        if "observation.image" in f:
            f["observation.image"].append(np.asarray(obs["pixels"], np.uint8))
        else:
            f["observation.environment_state"].append(np.asarray(obs["environment_state"], np.float32))
        f["observation.state"].append(np.asarray(obs["agent_pos"], np.float32))
        f["action"].append(action)
        f["next.reward"].append(np.array([reward], np.float32))
        f["next.done"].append(np.array([done], bool))
        f["next.success"].append(np.array([success], bool))


class _Recording:
    """The env, with each step recorded into `PushTFrames` (and the command noise added); everything else is
    the env's."""

    def __init__(self, env, frames: PushTFrames, noise: CommandNoise | None, expected_run):
        self._env, self._frames, self._obs = env, frames, None
        self._noise, self._draws, self._t = noise, None, 0
        self._expected = None if expected_run is None else np.asarray(expected_run, np.float32).reshape(-1, 2)

    def __getattr__(self, name):
        return getattr(self._env, name)

    def reset(self, **kwargs):
        obs, info = self._env.reset(**kwargs)
        self._obs, self._t = obs, 0
        if self._noise is not None:  # every step's draw at once: the stream's prefix is the same
            self._draws = self._noise.draws(int(getattr(self._env, "_max_episode_steps", 0)) or 1000)
        return obs, info

    def step(self, action):
        target = np.asarray(action, np.float64)
        run = target
        if target.shape == (2,) and np.all(np.isfinite(target)):  # else the env's own error
            target = _run_target(target)
            run = target if self._noise is None else _run_target(target.astype(np.float64) + self._draws[self._t])
            if self._expected is not None and not (
                self._t < len(self._expected) and np.array_equal(run, self._expected[self._t])
            ):
                raise ValueError(f"replay: step {self._t} ran {run.tolist()}, the list's actions differ")
        obs, reward, terminated, truncated, info = self._env.step(run)
        self._t += 1
        done = bool(terminated or truncated)
        self._frames._record(self._obs, target, float(reward), done, bool(info["is_success"]))
        self._obs = obs
        return obs, reward, terminated, truncated, info
