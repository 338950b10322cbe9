"""An episode's frames and their LeRobot features, and the writer that records them (with the LeRobot
step that is batched here and the library bars that are silenced)."""

from __future__ import annotations

import contextlib
import json
from pathlib import Path

import numpy as np

from lerobot_gcs_push.generate.config import (
    EPISODES_META,
    GenerateConfig,
)
from lerobot_gcs_push.pusht.dataset import pusht_feature_keys, pusht_features
from lerobot_gcs_push.registration import SCENES
from lerobot_gcs_push.scene import (
    Scene,
)

FEATURE_KEYS = ("observation.image", "observation.state", "observation.environment_state", "action")


def features(scene: Scene, image_size: int) -> dict:
    """The dataset's features; the environment state is the box's position, or a rotating slider's pose."""
    slider = list(scene.kind.state_names)
    return {
        "observation.image": {
            "dtype": "image",
            "shape": (image_size, image_size, 3),
            "names": ["height", "width", "channel"],
        },
        "observation.state": {"dtype": "float32", "shape": (2,), "names": ["finger_x", "finger_y"]},
        "observation.environment_state": {"dtype": "float32", "shape": (len(slider),), "names": slider},
        "action": {"dtype": "float32", "shape": (2,), "names": ["finger_target_x", "finger_target_y"]},
    }


class EpisodeFrames:
    """A rollout's frames as the dataset stores them; pass it to `rollout` as `on_step`."""

    def __init__(self, scene: Scene):
        self.kind = scene.kind
        self.frames: dict[str, list] = {k: [] for k in FEATURE_KEYS}

    def __call__(self, obs, action, info) -> None:
        state = self.kind.state(info["slider_pose"])
        self.frames["observation.image"].append(obs["pixels"])
        self.frames["observation.state"].append(np.asarray(obs["agent_pos"], np.float32))
        self.frames["observation.environment_state"].append(np.asarray(state, np.float32))
        self.frames["action"].append(np.asarray(action, np.float32))

    def __len__(self) -> int:
        return len(self.frames["action"])

    def arrays(self) -> dict[str, np.ndarray]:
        return {k: np.stack(v) for k, v in self.frames.items()}


@contextlib.contextmanager
def _batched_image_embedding():
    """Within the block, LeRobot's writer and its aggregation embed PNG bytes in one batched call per table,
    quietly.

    lerobot 0.6.1 embeds them row by row (`datasets.map(embed_table_storage, batched=False)`), which
    rebuilds the Arrow schema for every frame: 3.7 of the writer's 6 ms per 96x96 frame, paid again for
    every frame when the shards are merged. Batched, the same function gives the same table (the dataset
    tests read the images back). Scoped to our writer and merge so a user's own LeRobot code is untouched;
    if a later LeRobot moves the function, the unpatched path still works.
    """
    try:
        from datasets.table import embed_table_storage
        from lerobot.datasets import dataset_writer, io_utils
    except ImportError:
        yield
        return
    # Each module looks the function up in its own namespace (the writer imported it by name).
    modules = [m for m in (dataset_writer, io_utils) if getattr(m, "embed_images", None) is not None]
    originals = [m.embed_images for m in modules]

    def embed_images(dataset):
        fmt = dataset.format
        return dataset.with_format("arrow").map(embed_table_storage, batched=True).with_format(**fmt)

    with _quiet_library_bars():
        for m in modules:
            m.embed_images = embed_images
        try:
            yield
        finally:
            for m, original in zip(modules, originals, strict=True):
                m.embed_images = original


@contextlib.contextmanager
def _quiet_library_bars():
    """No library bars under our own one bar per stage: `datasets` draws "Generating train split" and
    "Map" for every episode saved or loaded, LeRobot's aggregation "Copy data and videos". LeRobot's own
    SuppressProgressBars turns datasets' bars back on when it exits, so that switch is held off too."""
    from datasets.utils import logging as datasets_logging
    from lerobot.datasets import aggregate

    bars_were_on = datasets_logging.is_progress_bar_enabled()
    enable, library_tqdm = datasets_logging.enable_progress_bar, aggregate.tqdm
    datasets_logging.disable_progress_bar()
    datasets_logging.enable_progress_bar = lambda: None
    aggregate.tqdm = _SilentTqdm
    try:
        yield
    finally:
        datasets_logging.enable_progress_bar, aggregate.tqdm = enable, library_tqdm
        if bars_were_on:
            enable()


class _SilentTqdm:
    """Stands in for the `tqdm` module inside lerobot.datasets.aggregate."""

    @staticmethod
    def tqdm(iterable=None, *args, **kwargs):
        from tqdm.auto import tqdm

        return tqdm(iterable, *args, **{**kwargs, "disable": True})


class _Writer:
    """Writes episodes into a new LeRobotDataset at `root` (a job's staging folder)."""

    def __init__(self, cfg: GenerateConfig, root: Path):
        from lerobot.datasets.lerobot_dataset import LeRobotDataset

        scene = SCENES[cfg.starts.env_id]
        pusht = scene.kind.lerobot_pusht_data  # lerobot/pusht's features, its image as video
        self.task = scene.task
        self.keys = pusht_feature_keys(cfg.obs_type) if pusht else FEATURE_KEYS
        self.ds = LeRobotDataset.create(
            repo_id=cfg.output.repo_id,
            fps=cfg.fps,
            features=pusht_features(cfg.image_size, cfg.obs_type) if pusht else features(scene, cfg.image_size),
            root=root,
            robot_type=None if pusht else "gcs_push_finger",
            use_videos=pusht and "observation.image" in self.keys,
            video_backend="pyav",
        )

    def add(self, arrays: dict[str, np.ndarray]) -> None:
        for t in range(len(arrays["action"])):
            self.ds.add_frame({k: arrays[k][t] for k in self.keys} | {"task": self.task})
        with _batched_image_embedding():
            self.ds.save_episode()

    def finish(self) -> None:
        self.ds.finalize()


def read_episode_metadata(root) -> list[dict]:
    path = Path(root) / EPISODES_META
    return [json.loads(line) for line in path.read_text().splitlines() if line.strip()]
