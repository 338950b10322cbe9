"""A dataset as its starts and actions: the small list that rebuilds it.

The sims are deterministic (gym-pusht's pymunk and the Drake envs without disturbances), so an episode is
its start and the actions the env ran. `generate` writes that list beside every dataset
(`meta/gcs_push_replay.json`); `generate --initial_conditions=<that list>` replays it (`--expert=replay`,
the default for a list whose entries all carry "actions"), which rebuilds the dataset in the time the sim
and the renderer take, with no planning. A long generation is so committed in stages as lists of a few MB.

Each entry is its initial condition (box, finger, heading, pusht_state: what `load_initial_conditions`
reads) plus "actions", one row per frame (an episode recorded under DART's noise adds "command_noise" and
"labels", the clean commands its dataset holds; one that went on past gym-pusht's success adds "finish"), as
float32 values written in their shortest exact form. gym-pusht runs those float32 actions, so its replay
repeats every stored value; the Drake envs ran the experts' float64 commands, so there the replayed states
differ by float32's rounding (5e-7 m) and the images not at all.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

REPLAY_META = "meta/gcs_push_replay.json"
START_KEYS = ("box", "finger", "heading", "pusht_state")
# What an entry holds besides its start: the actions the env ran and, for an episode recorded under DART's
# command noise, that noise and the labels the dataset holds (`pusht.dataset.CommandNoise`); for one that
# went on past gym-pusht's success, where it ended (`pusht.finish.Finish`).
REPLAY_KEYS = ("actions", "labels", "command_noise", "finish")


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


def _rows(actions) -> str:
    return ",".join(f"[{','.join(_number(v) for v in row)}]" for row in np.asarray(actions, np.float32))


def entry_line(entry: dict) -> str:
    """One entry as one line of JSON: the start's keys, then the actions (exact float32) and, for a DART
    episode, its noise and labels."""
    head = {k: entry[k] for k in START_KEYS if entry.get(k) is not None}
    for key in ("command_noise", "finish"):
        if entry.get(key) is not None:
            head[key] = entry[key]
    line = f'{json.dumps(head)[:-1]}, "actions": [{_rows(entry["actions"])}]'
    if entry.get("labels") is not None:
        line += f', "labels": [{_rows(entry["labels"])}]'
    return line + "}"


def write_replay(path: Path, entries: list[dict]) -> None:
    """The list, one episode a line (so that a list grown by a later stage diffs by its new lines)."""
    lines = ",\n".join(entry_line(e) for e in entries)
    Path(path).write_text(f"[\n{lines}\n]\n")


def dataset_replay(root: Path, metas: list[dict]) -> list[dict]:
    """Each episode of a finished dataset as a list entry: its start (from the episodes' metadata, in
    episode order) and actions (from the dataset's own data files). A DART episode's stored actions are its
    labels; what its env ran follows from them and its noise (`CommandNoise.commands_run`)."""
    import pyarrow.parquet as pq

    from lerobot_gcs_push.pusht.dataset import CommandNoise

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
    entries = []
    for meta, stored in zip(metas, np.split(action[order], np.cumsum(counts)[:-1])):
        entry = start_of(meta)
        if "command_noise" in meta:
            noise = CommandNoise.of(meta["command_noise"])
            entry |= {"command_noise": noise.spec(), "actions": noise.commands_run(stored), "labels": stored}
        else:
            entry["actions"] = stored
        if "finish" in meta:
            entry["finish"] = meta["finish"]
        entries.append(entry)
    return entries


def start_of(meta: dict) -> dict:
    """The initial condition an episode's metadata records, in `load_initial_conditions`'s keys."""
    if "pusht_state_initial" in meta:  # gym-pusht's start: box, finger and heading follow from it
        return {"pusht_state": meta["pusht_state_initial"]}
    start = {"box": meta["box_initial"], "finger": meta["finger_initial"]}
    if "heading_initial" in meta:
        start["heading"] = meta["heading_initial"]
    return start
