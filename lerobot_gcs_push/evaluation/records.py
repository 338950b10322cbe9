"""What an evaluation folder holds: `runs.jsonl` (one finished run a line), each run's trajectory, its
videos, and the fingerprints of the weights its runs were made with."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np

from lerobot_gcs_push.evaluation.config import GCS_POLICIES, EvaluateConfig
from lerobot_gcs_push.files import atomic_path

TIMING_FIELDS = ("run_time_s", "plan_time_s", "total_time_s")


def read_runs(path: Path) -> list[dict]:
    """Finished runs; a line cut short by a kill is dropped (its run is simply done again)."""
    if not path.exists():
        return []
    out = []
    for line in path.read_text().splitlines():
        try:
            out.append(json.loads(line))
        except json.JSONDecodeError:
            continue
    return out


def _key(rec: dict) -> tuple:
    return rec["policy"], bool(rec["disturbances"]), int(rec["initial_condition_index"]), int(rec["run"])


def weights_fingerprint(policy: str) -> str:
    """The first 16 hex digits of the sha256 of a learned policy's model.safetensors."""
    from lerobot_gcs_push.artifacts.shipped import shipped_path

    h = hashlib.sha256()
    with open(Path(shipped_path(policy)) / "model.safetensors", "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()[:16]


def changed_weights(cfg: EvaluateConfig, unrecorded_changed: bool = False) -> list[str]:
    """Learned policies of cfg whose weights differ from those that made the runs already in output_dir.

    A policy is named by its folder, and retraining into the same folder is common: without this check a
    re-run would resume and mix the old weights' runs with the new ones' under one label. Folders written
    before weights were recorded count as unchanged unless `unrecorded_changed`.
    """
    path = Path(cfg.output_dir) / "settings.json"
    if not path.is_file():
        return []
    stored = json.loads(path.read_text()).get("policy_weights", {})
    learned = [p for p in cfg.policies if p not in GCS_POLICIES]
    return [p for p in learned if stored.get(p) != weights_fingerprint(p) and (p in stored or unrecorded_changed)]


def _slug(label: str) -> str:
    return "".join(c if c.isalnum() else "_" for c in label).strip("_")


def video_path(out: Path, label: str, ic_index: int) -> Path:
    """Where run 0 of a variant on an initial condition is filmed (the first `videos` conditions)."""
    return Path(out) / "videos" / f"{_slug(label)}_ic{ic_index:03d}.mp4"


class Trajectory:
    """A run's states, one row per step and the final state, as saved beside its record: the `info` entries
    its slider kind names (`trajectory_keys`: finger and box positions, and a rotating slider's pose)."""

    def __init__(self, keys: tuple[str, ...]):
        self.rows: dict[str, list[np.ndarray]] = {k: [] for k in keys}

    def add(self, info: dict) -> None:
        for key, rows in self.rows.items():
            rows.append(np.asarray(info[key], float))

    def add_final(self, summary: dict) -> None:
        """The state the episode ended in, from the rollout's summary (no step follows it)."""
        for key, rows in self.rows.items():
            rows.append(np.asarray(summary[f"{key}_final"], float))

    def save(self, path: Path) -> None:
        arrays = {key: np.array(rows) for key, rows in self.rows.items()}
        with atomic_path(path) as tmp, open(tmp, "wb") as f:
            np.savez_compressed(f, **arrays)
