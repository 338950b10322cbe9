"""gym-pusht demonstrations as LeRobot's keypoint observations, rebuilt from replay lists with no planning.

A replay list (`gcs-push generate`'s `meta/gcs_push_replay.json`) holds each episode's start and the float32
targets gym-pusht ran (and, for DART's noisy episodes, the clean labels that are learnt). Replayed in
gym-pusht with `obs_type="environment_state_agent_pos"`, the env gives exactly what LeRobot's `pusht` env
maps to `observation.state` (the agent, px) and `observation.environment_state` (the T's 8 keypoints, 16
values, px); each episode must end at the success it was recorded with, or the list does not belong to
this gym-pusht.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

STATE, ENV_STATE, ACTION = "observation.state", "observation.environment_state", "action"
KEYS = (STATE, ENV_STATE, ACTION)
# Part of the cache's key: arrays replayed before the float32 targets were run exactly (2026-12-07) differ
# by up to 3e-5 px and are not reused.
REPLAY_VERSION = "2"


@dataclass
class Episodes:
    """Frames of consecutive episodes: `arrays[key]` (N, dim) float32 and `ends` (the index after each)."""

    arrays: dict[str, np.ndarray]
    ends: np.ndarray

    def __len__(self) -> int:
        return len(self.ends)

    @property
    def frames(self) -> int:
        return int(self.ends[-1]) if len(self.ends) else 0

    def starts(self) -> np.ndarray:
        return np.concatenate([[0], self.ends[:-1]]).astype(int)

    def labels_ahead(self, frames: int) -> Episodes:
        """Each frame labelled with its episode's action `frames` later (the last action where that is past
        the end): commands that lead further, on the same states, without planning again."""
        if frames < 0:
            raise ValueError(f"labels can be taken later, not earlier: got {frames} frames")
        if frames == 0:
            return self
        index = np.arange(self.frames)
        last = np.repeat(self.ends - 1, np.diff(np.concatenate([[0], self.ends])))
        arrays = dict(self.arrays) | {ACTION: self.arrays[ACTION][np.minimum(index + frames, last)]}
        return Episodes(arrays, self.ends)


def read_lists(paths, episodes: int | None = None) -> list[dict]:
    """The episodes of the replay lists in order, the first `episodes` of them (all: None)."""
    demos = []
    for path in paths:
        path = Path(path)
        if not path.is_file():
            raise FileNotFoundError(f"no replay list at {path} (gcs-push generate writes meta/gcs_push_replay.json)")
        entries = json.loads(path.read_text())
        if not isinstance(entries, list) or any("actions" not in e or "pusht_state" not in e for e in entries):
            raise ValueError(f"{path} is not a gym-pusht replay list (entries with pusht_state and actions)")
        demos += entries
    if episodes is not None:
        if episodes > len(demos):
            raise ValueError(f"{episodes} episodes asked, the lists hold {len(demos)}")
        demos = demos[:episodes]
    return demos


def replay(demos: list[dict], progress: bool = True, hold_frames: int = 0) -> Episodes:
    """Each demonstration run in gym-pusht from its start, its observations recorded before each action.
    `hold_frames`: after its success, so many frames more in which the agent is held where it was then (the
    command is its position): a demonstration that ends at the threshold shows nothing of stopping there."""
    import gym_pusht  # noqa: F401  (registers the env)
    import gymnasium as gym
    from tqdm.auto import tqdm

    from lerobot_gcs_push.pusht.env import GYM_PUSHT_ID, GYM_PUSHT_STEPS
    from lerobot_gcs_push.pusht.frame import reset_to_state

    env = gym.make(GYM_PUSHT_ID, obs_type="environment_state_agent_pos", max_episode_steps=GYM_PUSHT_STEPS)
    out: dict[str, list] = {k: [] for k in KEYS}
    ends = []
    for k, demo in enumerate(tqdm(demos, desc="replaying", unit="episode", disable=not progress)):
        obs, _ = env.reset(options={"reset_to_state": reset_to_state(demo["pusht_state"])})
        success = False
        # A DART episode's env ran its "actions" (labels plus noise); what is learnt is its "labels".
        labels = demo.get("labels", demo["actions"])
        if len(labels) != len(demo["actions"]):
            raise ValueError(f"demonstration {k}: {len(labels)} labels for {len(demo['actions'])} actions")
        for action, label in zip(demo["actions"], labels):
            out[STATE].append(np.asarray(obs["agent_pos"], np.float32))
            out[ENV_STATE].append(np.asarray(obs["environment_state"], np.float32))
            out[ACTION].append(np.asarray(label, np.float32))
            # The float32 the list stores: its shortest decimal read as float64 would be another target.
            obs, _, _, _, info = env.step(np.asarray(action, np.float32).astype(np.float64))
            success = bool(info["is_success"])
        if not success:
            raise ValueError(f"demonstration {k} did not end at its success on replay: not this gym-pusht's list")
        hold = np.asarray(obs["agent_pos"], np.float32)
        for _ in range(hold_frames):
            out[STATE].append(np.asarray(obs["agent_pos"], np.float32))
            out[ENV_STATE].append(np.asarray(obs["environment_state"], np.float32))
            out[ACTION].append(hold)
            obs, *_ = env.step(hold.astype(np.float64))
        ends.append(len(out[ACTION]))
    env.close()
    return Episodes({k: np.stack(v) for k, v in out.items()}, np.array(ends, np.int64))


def load(paths, episodes: int | None = None, cache_dir=None, progress: bool = True, hold_frames: int = 0) -> Episodes:
    """`replay` of the lists, kept in `cache_dir` under the hash of what was replayed (a rebuild is minutes)."""
    if hold_frames < 0:
        raise ValueError(f"hold_frames must be >= 0, got {hold_frames}")
    demos = read_lists(paths, episodes)
    key = hashlib.sha256((REPLAY_VERSION + json.dumps(demos, sort_keys=True)).encode()).hexdigest()[:16]
    key += f"_hold{hold_frames}" if hold_frames else ""
    cached = Path(cache_dir) / f"keypoints_{key}.npz" if cache_dir else None
    if cached is not None and cached.is_file():
        with np.load(cached) as z:
            return Episodes({k: z[k] for k in KEYS}, z["ends"])
    data = replay(demos, progress, hold_frames)
    if cached is not None:
        cached.parent.mkdir(parents=True, exist_ok=True)
        tmp = cached.with_suffix(".tmp.npz")
        np.savez(tmp, ends=data.ends, **data.arrays)
        tmp.replace(cached)
    return data
