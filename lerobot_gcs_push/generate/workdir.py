"""The work folder beside a dataset: finished episodes, one file each, and the settings they were made with."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from lerobot_gcs_push.files import atomic_path
from lerobot_gcs_push.generate.config import (
    _IMPLICIT_SETTINGS,
)
from lerobot_gcs_push.settings import changed, describe


class WorkDir:
    """Finished episodes of a run, one file each, plus the run's settings (to refuse mixing runs)."""

    def __init__(self, path: Path):
        self.path = path

    def settings_file(self) -> Path:
        return self.path / "settings.json"

    def open(self, settings: dict, resume: bool) -> None:
        if self.path.exists():
            if not resume:
                raise FileExistsError(
                    f"an interrupted run left {self.path}: pass --resume=true to continue it "
                    "or --overwrite=true to start again"
                )
            old = json.loads(self.settings_file().read_text()) if self.settings_file().exists() else None
            diff = changed(old, _IMPLICIT_SETTINGS | settings, _IMPLICIT_SETTINGS) if old is not None else {}
            if diff:
                raise ValueError(f"--resume with different settings than the interrupted run: {describe(diff)}")
        self.path.mkdir(parents=True, exist_ok=True)
        with atomic_path(self.settings_file()) as tmp:
            tmp.write_text(json.dumps(settings, indent=1))

    def episode_file(self, index: int) -> Path:
        return self.path / f"episode_{index:06d}.npz"

    def meta(self, index: int) -> dict:
        with np.load(self.episode_file(index), allow_pickle=False) as z:
            return json.loads(str(z["meta"]))

    def save(self, result: dict) -> None:
        meta = result["meta"]
        arrays = {k.replace(".", "__"): v for k, v in result["arrays"].items()}
        with atomic_path(self.episode_file(meta["index"])) as tmp, open(tmp, "wb") as f:
            np.savez_compressed(f, meta=json.dumps(meta), **arrays)

    def load_arrays(self, index: int) -> dict[str, np.ndarray]:
        with np.load(self.episode_file(index), allow_pickle=False) as z:
            return {k.replace("__", "."): z[k] for k in z.files if k != "meta"}
