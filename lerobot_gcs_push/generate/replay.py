"""A dataset as its starts and actions: the small list that rebuilds it.

The sims are deterministic (gym-pusht's pymunk and the Drake envs without disturbances), so an episode is
its start and the actions the env ran. `generate` writes that list beside every dataset
(`meta/gcs_push_replay.json`); `generate --initial_conditions=<that list>` replays it (`--expert=replay`,
the default for a list whose entries all carry "actions"), which rebuilds the dataset in the time the sim
and the renderer take, with no planning. A long generation is so committed in stages as lists of a few MB.

Each entry is its initial condition (box, finger, heading, pusht_state: what `load_initial_conditions`
reads) plus "actions", one row per frame, as float32 values written in their shortest exact form. gym-pusht
runs those float32 actions, so its replay repeats every stored value; the Drake envs ran the experts'
float64 commands, so there the replayed states differ by float32's rounding (5e-7 m) and the images not
at all.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

REPLAY_META = "meta/gcs_push_replay.json"
START_KEYS = ("box", "finger", "heading", "pusht_state")


class ReplayActions:
    """`rollout.Policy` that runs one episode's recorded actions (`load` them before each rollout). Past its
    last action it holds that action: a replay that has not ended by then did not repeat its episode, and
    the env's time limit ends it as a failure, which `generate` reports."""

    def __init__(self):
        self._actions = np.zeros((0, 2), np.float32)
        self._k = 0

    def load(self, actions) -> None:
        try:
            actions = np.asarray(actions, np.float32)
        except (ValueError, TypeError):  # ragged rows, or not numbers
            raise ValueError("replayed actions must be rows of numbers, all of one length") from None
        if actions.ndim != 2 or len(actions) == 0 or not np.all(np.isfinite(actions)):
            raise ValueError(f"replayed actions must be a non-empty list of finite rows, got shape {actions.shape}")
        self._actions = actions

    def reset(self, obs, info: dict, seed: int | None = None) -> None:
        self._k = 0

    def act(self, obs, info: dict) -> np.ndarray:
        action = self._actions[min(self._k, len(self._actions) - 1)]
        self._k += 1
        return action.copy()

    def episode_summary(self) -> dict:
        return {"plan_time_s": 0.0, "plan": None, "replans": 0}


def _number(x: np.float32) -> str:
    return np.format_float_positional(x, unique=True, trim="-")


def entry_line(start: dict, actions: np.ndarray) -> str:
    """One entry as one line of JSON: the start's keys, then the actions (exact float32)."""
    head = json.dumps({k: start[k] for k in START_KEYS if start.get(k) is not None})
    rows = ",".join(f"[{','.join(_number(v) for v in row)}]" for row in np.asarray(actions, np.float32))
    return f'{head[:-1]}, "actions": [{rows}]}}'


def write_replay(path: Path, starts: list[dict], actions: list[np.ndarray]) -> None:
    """The list, one episode a line (so that a list grown by a later stage diffs by its new lines)."""
    if len(starts) != len(actions):
        raise ValueError(f"{len(starts)} starts but {len(actions)} action lists")
    lines = ",\n".join(entry_line(s, a) for s, a in zip(starts, actions))
    Path(path).write_text(f"[\n{lines}\n]\n")


def dataset_replay(root: Path, metas: list[dict]) -> tuple[list[dict], list[np.ndarray]]:
    """The starts (from the episodes' metadata, in episode order) and actions (from the dataset's own data
    files) of a finished dataset."""
    import pyarrow.parquet as pq

    tables = [
        pq.read_table(f, columns=["episode_index", "frame_index", "action"])
        for f in sorted(root.glob("data/*/*.parquet"))
    ]
    episode = np.concatenate([t.column("episode_index").to_numpy() for t in tables])
    frame = np.concatenate([t.column("frame_index").to_numpy() for t in tables])
    action = np.concatenate([np.stack(t.column("action").to_numpy(zero_copy_only=False)) for t in tables]).astype(
        np.float32
    )
    # One sort by (episode, frame), then a split: each episode's rows in frame order.
    order = np.lexsort((frame, episode))
    counts = np.bincount(episode, minlength=len(metas))
    for i, meta in enumerate(metas):
        if counts[i] != meta["num_frames"]:
            raise ValueError(f"episode {i} of {root} has {counts[i]} frames, its metadata says {meta['num_frames']}")
    actions = np.split(action[order], np.cumsum(counts)[:-1])
    return [start_of(meta) for meta in metas], actions


def start_of(meta: dict) -> dict:
    """The initial condition an episode's metadata records, in `load_initial_conditions`'s keys."""
    if "pusht_state_initial" in meta:  # gym-pusht's start: box, finger and heading follow from it
        return {"pusht_state": meta["pusht_state_initial"]}
    start = {"box": meta["box_initial"], "finger": meta["finger_initial"]}
    if "heading_initial" in meta:
        start["heading"] = meta["heading_initial"]
    return start
